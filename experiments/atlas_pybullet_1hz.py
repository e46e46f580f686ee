"""The shipped PyBullet atlas at 1 Hz against the 2 Hz one it replaced, on the same held-out live probes (issue 33).

    python experiments/atlas_pybullet_1hz.py

Reads the 1 Hz build's 40 held-out live probes from experiments/cache/atlas_heldout_pybullet_1hz.jsonl (no probe
is simulated: a missing one is an error) and scores the shipped atlas (``plate_env/data/atlas_pybullet_pybullet.npz``)
and the 2 Hz atlas it replaced (read from git, commit 893bbe6) with :func:`plate_env.build.atlas.held_out_score`.
Writes experiments/results/atlas_pybullet_1hz.md.
"""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

from common import CACHE

from plate_env.build.atlas import held_out_score, held_out_specs, resolve_grid
from plate_env.run.executor import BackendSpec
from plate_env.run.sweeps import run_cached
from plate_env.surrogate.atlas import Atlas, load_atlas

#: The commit whose shipped PyBullet atlas was the 2 Hz one.
BEFORE = "893bbe6"
OUT = Path("experiments/results/atlas_pybullet_1hz.md")


def no_simulation(*args, **kwargs):
    raise SystemExit("a held-out probe is missing from the committed cache; this script simulates nothing")


def main() -> None:
    from plate_env.run import sweeps

    sweeps.make_executor = no_simulation  # every probe must come from the cache
    live = run_cached(BackendSpec.of("pybullet", n_workers=1), held_out_specs(resolve_grid("pybullet_1hz"), 40, 0),
                      Path(CACHE) / "atlas_heldout_pybullet_1hz.jsonl", executor="inprocess")
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "atlas_2hz.npz"
        old.write_bytes(subprocess.run(["git", "show", f"{BEFORE}:plate_env/data/atlas_pybullet_pybullet.npz"],
                                       check=True, capture_output=True).stdout)
        atlases = {f"2 Hz (9 f, 10-26 Hz; shipped at {BEFORE})": Atlas.load(old),
                   "1 Hz (17 f, 10-26 Hz; shipped now)": load_atlas("pybullet", "pybullet")}
        rows = []
        for label, atlas in atlases.items():
            lines, sigma_model = held_out_score(atlas, live)
            rows.append(f"| {label} |{lines[4][1:]} {sigma_model:.2f} |")
    head = lines[2].replace("| stable probes", "| atlas | stable probes") + " sigma_model [deg/s] |"
    text = ["# The PyBullet atlas at 1 Hz against the 2 Hz one it replaced", "",
            "Command: `python experiments/atlas_pybullet_1hz.py`. The same "
            f"{len(live)} live PyBullet probes at held-out points (off-grid f_p, omega_n, alpha; the 1 Hz build's "
            "held-out set, "
            "experiments/cache/atlas_heldout_pybullet_1hz.jsonl) through each atlas. Build report: "
            "experiments/results/atlas_pybullet_pybullet.md.", "",
            head, "|---|---|---|---|---|---|---|---|---|", *rows, ""]
    OUT.write_text("\n".join(text))
    print("\n".join(text))


if __name__ == "__main__":
    main()
