"""The PyBullet atlas at 1 Hz against the shipped 2 Hz one (issue 33): built, better at predicting held-out
probes, not shipped, because identification through it refuses more objects; this script measures why.

    python experiments/atlas_pybullet_1hz.py

Simulates nothing (a probe missing from the committed caches is an error):

1. builds the 1 Hz atlas from its committed probe cache (experiments/cache/atlas_pybullet_1hz.jsonl, grid
   experiments/cache/pybullet_1hz_grid.json: 17 f 10-26 Hz x 10 omega_n x 4 alpha, 1 placement) with the command
   below, into a temporary directory;
2. scores it and the shipped 2 Hz atlas on the same 40 live held-out probes (the 1 Hz build's held-out set,
   :func:`plate_env.build.atlas.held_out_score`);
3. compares the two builds where their grids meet (even f): the same probe specification simulated twice, in
   sequences of 9 and of 17 probes per scene;
4. identifies the 24 held-out PyBullet objects of the forward-model study (experiments/forward_models.py lomo,
   seed 600, 10-26 Hz at 2 Hz) through each atlas alone (its own sigma_model): no-estimate share, median error,
   95 % coverage.

Writes experiments/results/atlas_pybullet_1hz.md.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
from common import CACHE, DATA, data_of

from plate_env.build.atlas import held_out_score, held_out_specs, resolve_grid
from plate_env.cli import main as cli
from plate_env.identify.forward import ForwardModel, Member
from plate_env.identify.inference import identify_atlas
from plate_env.run import sweeps
from plate_env.run.executor import BackendSpec
from plate_env.surrogate.atlas import Atlas, load_atlas

GRID = f"{CACHE}/pybullet_1hz_grid.json"
BUILD = ["build", "atlas", "--physics", "pybullet", "--grid", GRID, "--repeats", "1", "--seed", "0", "--held-out", "40",
         "--name", "pybullet_1hz", "--cache-dir", CACHE, "--no-progress"]
OUT = Path("experiments/results/atlas_pybullet_1hz.md")


def no_simulation(*args, **kwargs):
    raise SystemExit("a probe is missing from the committed caches; this script simulates nothing")


def identification(atlas: Atlas, objects: list, tables: list) -> tuple[int, float, float, float, int]:
    """(no-estimate count, median relative error among the estimated, 95 % coverage counting no estimate as a miss,
    median |alpha error| in deg over every object (the posterior's alpha, refused or not), refusals of objects whose
    alpha lies within 6 deg of the atlas's alpha edges) of ``tables`` through ``atlas`` alone."""
    fm = ForwardModel("atlas", (Member(atlas, float(atlas.provenance["sigma_model_deg_s"])),))
    errs, covered, none, alpha_err, near_edge = [], 0, 0, [], 0
    lo_a, hi_a = float(atlas.alpha[0]), float(atlas.alpha[-1])
    for o, t in zip(objects, tables, strict=True):
        e = identify_atlas(t, fm)
        alpha_err.append(abs(math.degrees(e.alpha - o.alpha)))
        if e.reason is not None:
            none += 1
            near_edge += min(o.alpha - lo_a, hi_a - o.alpha) <= math.radians(6.0)
            continue
        errs.append(abs(e.omega_n / o.omega_n - 1.0))
        lo, hi = e.omega_n_ci95
        covered += lo <= o.omega_n <= hi
    return (none, float(np.median(errs)) if errs else math.inf, covered / len(objects), float(np.median(alpha_err)),
            near_edge)


def main() -> None:
    sweeps.make_executor = no_simulation
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "atlas_pybullet_1hz.npz"
        if cli([*BUILD, "--out", str(out)]) != 0:
            raise SystemExit("the 1 Hz build failed")
        atlases = {"2 Hz (shipped: 9 f)": load_atlas("pybullet", "pybullet"), "1 Hz (17 f)": Atlas.load(out)}
    live = sweeps.run_cached(BackendSpec.of("pybullet", n_workers=1), held_out_specs(resolve_grid(GRID), 40, 0),
                             Path(CACHE) / "atlas_heldout_pybullet_1hz.jsonl", executor="inprocess")
    truth, tables = data_of("pybullet", None)
    text = ["# The PyBullet atlas at 1 Hz against the shipped 2 Hz one", "",
            "Command: `python experiments/atlas_pybullet_1hz.py` (simulates nothing; the 1 Hz atlas is built from its "
            "committed cache by `plate-env " + " ".join(BUILD) + "`).", "",
            f"## The same {len(live)} live probes at held-out points (off-grid f_p, omega_n, alpha)", ""]
    rows = []
    for label, atlas in atlases.items():
        lines, sigma_model = held_out_score(atlas, live)
        rows.append(f"| {label} |{lines[4][1:]} {sigma_model:.2f} |")
    text += [lines[2].replace("| stable probes", "| atlas | stable probes") + " sigma_model [deg/s] |",
             "|---|---|---|---|---|---|---|---|---|", *rows, ""]
    old, new = atlases["2 Hz (shipped: 9 f)"], atlases["1 Hz (17 f)"]
    idx = [int(np.flatnonzero(new.f_hz == f)[0]) for f in old.f_hz]
    mn, pn, mo, po = new.mean[idx], new.p_unstable[idx], old.mean, old.p_unstable
    text += ["## The two builds where their grids meet (the same probe specifications, even f)", "",
             "| f_p [Hz] | stability calls agreeing | median abs difference where both stable [deg/s] |",
             "|---|---|---|"]
    for j, f in enumerate(old.f_hz):
        both = (pn[j] < 0.5) & (po[j] < 0.5)
        diff = f"{np.median(np.abs(mn[j] - mo[j])[both]):.1f}" if both.any() else "-"
        text.append(f"| {f:g} | {np.mean((pn[j] > 0.5) == (po[j] > 0.5)):.2f} | {diff} |")
    both = (pn < 0.5) & (po < 0.5)
    text += [f"| all | {np.mean((pn > 0.5) == (po > 0.5)):.2f} | {np.median(np.abs(mn - mo)[both]):.1f} |", "",
             f"## Identification of the {len(truth)} held-out objects of the forward-model study (each atlas alone)",
             "",
             "| atlas | no estimate | of which alpha within 6 deg of the grid's edge | median error among estimated | "
             "95 % coverage (no estimate = miss) | median abs alpha error [deg] |", "|---|---|---|---|---|---|"]
    for label, atlas in atlases.items():
        none, med, cov, da, near = identification(atlas, DATA["pybullet"].objects(), tables)
        text.append(f"| {label} | {none} of {len(truth)} | {near} | {100 * med:.1f} % | {cov:.2f} | {da:.1f} |")
    text += ["", "Reading: the 1 Hz atlas predicts held-out probes better and reads alpha more sharply, so objects "
             "whose friction angle lies near the grid's 30 or 60 deg edge (the study's prior is 30-60 deg, the grid's "
             "own range) get posterior mass in the edge column and the alpha-edge rule gives no estimate: the rule "
             "does its job (an object beyond the edge would be read there with a biased omega_n), and two of the "
             "refused estimates are indeed far off. Inflating the 1 Hz atlas's spread or sigma_model (tried: x1-3, "
             "+5-10 % of the mean) does not bring the refusals down to the 2 Hz atlas's. The same probe specification "
             "simulated in two builds also disagrees on stability where the sheet is near its limit (18-26 Hz). "
             "Not shipped: the next step is alpha columns beyond the prior (20 and 70 deg: 340 probes, ~50 min of "
             "one core), so that the edge lies outside the objects' range."]
    OUT.write_text("\n".join(text) + "\n")
    print("\n".join(text))


if __name__ == "__main__":
    main()
