"""12 deg with slipped probes kept: does the paper's 12 deg hump appear if runs that slipped are read anyway?
(issue 27, item 3)

    python experiments/kept_12deg.py          # reads validate_paper.py's caches; simulates nothing

At 12 deg the tile-link models lose soft discs before any hump: the point mass slips, the rigid tiles fold (a
detected, reported failure). The paper rejects a run whose centre moves more than 10 mm, the project's ``slipped``;
how strictly the paper applied that to its 12 deg curves is not stated. This reading keeps a slipped probe's
omega_B over the whole periods measured before the slip (``periods_measured`` > 0; the same value the probe
reports) and fits the first hump as validate_paper.py does (``fit_sweep``: f0 inside the probes it used). Folded,
overturned and other failures stay unstable: they are the model's failure, not a run the paper could have kept.

Objects: Table 1's and Section 5's at alpha 36.9 deg (1.4, 3.5, 6.5, 10, 14, 23, 33pi), every cached placement.
The bar (issue 27, item 3): a hump at 11-14 Hz for every omega_n <= 10pi, with f0 rising with omega_n as in the
paper (Eq. 10 at 12 deg: f0 = (omega_n + 64.51) / 5.65, 11.7 Hz at 1.4pi to 13.2 Hz at 10pi). Checked on medians
over placements; an object fitted in fewer than half its placements has no median. Writes
experiments/results/kept_12deg.{json,md}.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import common
import numpy as np
from common import kept

SCRIPT = "experiments/kept_12deg.py"
OBJECTS_PI = (*common.FIG8_OMEGAS_PI[12.0], *common.SEC5_STIFF_PI)
BAR_HZ = common.FIG10_RANGE[12.0]
READINGS = ("default", "kept")


def median_f0(fits: list) -> float | None:
    """Median f0 over placements, or None when fewer than half of them fitted."""
    f0 = [f.f0 for f in fits if f.ok]
    return float(np.median(f0)) if f0 and 2 * len(f0) >= len(fits) else None


def bar(medians: dict[float, float | None]) -> dict:
    """The item-3 bar on the soft objects' (omega_n <= 10pi) median f0: all fitted, all in 11-14 Hz, and the
    least-squares slope of f0 on omega_n positive."""
    soft = {w: medians.get(w) for w in common.FIG8_OMEGAS_PI[12.0]}
    have = {w: f for w, f in soft.items() if f is not None}
    slope = float(np.polyfit(list(have), list(have.values()), 1)[0]) if len(have) >= 2 else None
    in_range = all(BAR_HZ[0] <= f <= BAR_HZ[1] for f in have.values())
    return {"fitted_pi": sorted(have), "missing_pi": sorted(set(soft) - set(have)), "all_in_11_14_hz": in_range,
            "slope_hz_per_pi": slope, "meets_bar": len(have) == len(soft) and in_range and (slope or 0.0) > 0}


def model_table(model: str, cache_dir: Path) -> dict | None:
    got = common.cached_sweeps(model, cache_dir)
    out: dict = {"objects": {}}
    for reading in READINGS:
        medians = {}
        for w in OBJECTS_PI:
            sw = next(s for s in common.plan(model)
                      if s.omega_pi == w and s.alpha_deg == common.CHEESE and s.a_p_deg == 12.0)
            runs = [got[(sw, p)] for p in range(common.PLACEMENTS[model]) if (sw, p) in got]
            if not runs:
                return None
            fits = [common.fit_sweep(kept(r) if reading == "kept" else r) for r in runs]
            medians[w] = median_f0(fits)
            out["objects"].setdefault(f"{w:g}", {})[reading] = [
                {"f0_hz": f.f0, "omega_max_deg_s": f.omega_max, "r2": f.r2} if f.ok else {"why": f.reason}
                for f in fits]
            if reading == "kept":
                out["objects"][f"{w:g}"]["slipped_kept"] = [
                    sum(r.reason == "slipped" and r.periods_measured > 0 for r in run) for run in runs]
        out[reading] = {"median_f0_hz": {f"{w:g}": v for w, v in medians.items()}, "bar": bar(medians)}
    return out


def _cell(fits: list[dict]) -> str:
    ok = [f for f in fits if "f0_hz" in f]
    if not ok:
        return f"no fit (0/{len(fits)})"
    f0 = ", ".join(f"{f['f0_hz']:.1f}" for f in ok)
    return f"{f0} Hz ({len(ok)}/{len(fits)})"


def markdown(res: dict) -> str:
    md = ["# 12 deg with slipped probes kept (issue 27, item 3)", "",
          f"Regenerate: `python {SCRIPT}` (reads `validate_paper.py`'s caches; simulates nothing). Objects at alpha "
          "36.9 deg, A_p 12 deg, every cached placement. `default`: the table's rule (slipped, folded and other "
          "unstable probes dropped). `kept`: a slipped probe's omega_B over the periods before its slip read as "
          "stable; folded and other failures still dropped. Cells: first-hump f0 per fitted placement (fitted / "
          "placements). Bar: every omega_n <= 10pi fitted (median over placements) at 11-14 Hz with f0 rising with "
          "omega_n (paper: 11.7 Hz at 1.4pi to 13.2 Hz at 10pi).", "",
          "| model | reading | " + " | ".join(f"{w:g}pi" for w in OBJECTS_PI) + " | soft objects' slope [Hz/pi] "
          "| bar |", "|---|---|" + "---|" * (len(OBJECTS_PI) + 2)]
    for model, t in res["models"].items():
        if t is None:
            md.append(f"| {model} | | " + " | ".join("not run" for _ in OBJECTS_PI) + " | | |")
            continue
        for reading in READINGS:
            b = t[reading]["bar"]
            slope = "-" if b["slope_hz_per_pi"] is None else f"{b['slope_hz_per_pi']:+.2f}"
            verdict = "met" if b["meets_bar"] else (
                "not met" + (f": no hump at {', '.join(f'{w:g}' for w in b['missing_pi'])}pi" if b["missing_pi"]
                             else "") + ("" if b["all_in_11_14_hz"] else "; f0 outside 11-14 Hz"))
            md.append(f"| {model} | {reading} | "
                      + " | ".join(_cell(t["objects"][f"{w:g}"][reading]) for w in OBJECTS_PI)
                      + f" | {slope} | {verdict} |")
    return "\n".join(md) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache-dir", default="experiments/cache")
    ap.add_argument("--out-dir", default="experiments/results")
    args = ap.parse_args()
    res = {"command": f"python {SCRIPT}", "commit": common.git_commit(), "bar_hz": list(BAR_HZ),
           "models": {m: model_table(m, Path(args.cache_dir)) for m in common.MODELS}}
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "kept_12deg.json").write_text(json.dumps(res, indent=1, default=float, allow_nan=False) + "\n")
    text = markdown(res)
    (out / "kept_12deg.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
