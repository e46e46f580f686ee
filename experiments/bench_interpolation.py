"""The atlas's interpolation: scipy's tensor-product "cubic" spline (what plate_env.surrogate.atlas uses) against
its "pchip" variant (no overshoot), on the shipped point-mass atlas's mean at A_p = 3 deg.

    python experiments/bench_interpolation.py [--points 20000] [--repeats 5]

Builds ``RegularGridInterpolator`` on (f_p, log omega_n, alpha) with each method, evaluates both at the same seeded
random points inside the grid, ``--repeats`` times each, and writes the median wall seconds of one evaluation and
their ratio (measured in the same run, with the load average) to experiments/results/bench_interpolation.json (the
source) and .md. Cited by the docstring of plate_env/surrogate/atlas.py.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "results" / "bench_interpolation"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=20_000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    from scipy.interpolate import RegularGridInterpolator
    from scipy.sparse.linalg import spsolve

    from plate_env.surrogate.atlas import load_atlas

    atlas = load_atlas("tilelink", "pointmass")
    axes = (np.asarray(atlas.f_hz, float), np.log(atlas.omega_n), np.asarray(atlas.alpha, float))
    values = np.ascontiguousarray(atlas.mean[:, 0], dtype=float)
    rng = np.random.default_rng(0)
    pts = np.stack([rng.uniform(a[0], a[-1], args.points) for a in axes], -1)
    load_start = os.getloadavg()
    seconds = {}
    for method, kw in (("cubic", {"solver": spsolve}), ("pchip", {})):
        interp = RegularGridInterpolator(axes, values, method=method, **kw)
        interp(pts[:10])  # any one-off set-up outside the timing
        runs = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            interp(pts)
            runs.append(time.perf_counter() - t0)
        seconds[method] = statistics.median(runs)
    report = {"atlas": "atlas_tilelink_pointmass (mean, A_p = 3 deg)", "points": args.points,
              "repeats": args.repeats, "median_s": seconds, "pchip_over_cubic": seconds["pchip"] / seconds["cubic"],
              "load_avg_start": load_start, "load_avg_end": os.getloadavg(),
              "command": f"python experiments/bench_interpolation.py --points {args.points} --repeats {args.repeats}"}
    OUT.with_suffix(".json").write_text(json.dumps(report, indent=1) + "\n")
    md = ["# Atlas interpolation: cubic against pchip", "",
          f"`{report['command']}` (writes this file from `bench_interpolation.json`). {args.points:,} random points "
          f"inside the shipped point-mass atlas's grid, median of {args.repeats} evaluations each, load average "
          f"{load_start[0]:.1f} at the start (a shared machine: read the ratio, measured in one run).",
          "", "| method | median s per evaluation |", "|---|---|",
          *(f"| {m} | {s:.4g} |" for m, s in seconds.items()), "",
          f"pchip / cubic: {report['pchip_over_cubic']:.0f}x.", ""]
    OUT.with_suffix(".md").write_text("\n".join(md))
    print("\n".join(md))


if __name__ == "__main__":
    main()
