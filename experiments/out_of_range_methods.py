"""Issue 37: the estimate contract for every method (atlas, Lorentz, calibrated) on sweeps beyond the range.

    python experiments/out_of_range_methods.py [--physics pointmass,rigid_fast] [--alphas 35,45,55] [--seed 0]
        [--cache experiments/cache/out_of_range_sweeps.jsonl] [--out experiments/results/out_of_range_methods.json]

Live 3-deg sweeps (16 probes, 10-40 Hz, placed) of 13.6 g discs on the point mass and on the rigid tiles
(``rigid_fast``, the faithful physics) at omega_n below (0.3, 0.5, 1, 1.2 pi) and above (50, 60, 100, 200 pi) every
shipped model's identifiable range, and inside it (3, 10, 30 pi: the price, answers lost), each read by every
estimator a user reaches on such data: the atlas method on the physics' own model and on the ``lab`` pool, the
Lorentz method on the paper's, the lab's and the physics' own lines, and the paper's calibration. Counts per
estimator: outside the range, confident estimates and those whose 95 % interval excludes the truth, bounds and
bounds on the wrong side; inside it, estimates. The sweeps are cached (``--cache``), so the same sweeps can be read
by another commit's code (run this file with that commit on ``PYTHONPATH``). Prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
import math
import warnings
from pathlib import Path

import numpy as np

F_HZ = np.arange(10.0, 41.0, 2.0)
OUTSIDE_PI = (0.3, 0.5, 1.0, 1.2, 50.0, 60.0, 100.0, 200.0)
INSIDE_PI = (3.0, 10.0, 30.0)
#: estimator label -> make_estimator keywords ("{own}": the physics' own model name)
ESTIMATORS = {"atlas own": dict(method="atlas", name="tilelink/{own}"),
              "atlas lab": dict(method="atlas", name="tilelink/{own}", forward="lab"),
              "lorentz own": dict(method="lorentz", name="tilelink/{own}"),
              "lorentz lab": dict(method="lorentz", name="lab/lab"),
              "lorentz paper": dict(method="lorentz", name="paper/pointmass"),
              "calibrated paper": dict(calibration="paper")}
#: identifiable ranges (pi rad/s) of the physics' own models
RANGE_PI = {"pointmass": (1.4, 45.0), "rigid_fast": (2.5, 45.0)}


def sweeps(physics: str, alphas: list[float], seed: int, cache: Path) -> list[dict]:
    """One placed sweep per (omega_n, alpha), live; read from / appended to ``cache`` (JSON lines)."""
    from plate_env.build.eval_sets import placed_sweeps
    from plate_env.core.objects import ObjectSpec
    from plate_env.core.probe_table import ProbeTable
    from plate_env.physics import make_physics

    have = {}
    if cache.is_file():
        for line in cache.read_text().splitlines():
            d = json.loads(line)
            have[(d["physics"], d["omega_pi"], d["alpha_deg"], d["seed"])] = d
    out = []
    for w in OUTSIDE_PI + INSIDE_PI:
        for a in alphas:
            key = (physics, w, a, seed)
            if key not in have:
                obj = ObjectSpec(omega_n=w * math.pi, alpha=math.radians(a))
                phys = make_physics("tilelink", model=physics)
                try:
                    res = phys.run(placed_sweeps([obj], F_HZ, 3.0, np.random.default_rng([seed, int(w * 100), int(a)])))
                finally:
                    phys.close()
                t = ProbeTable.from_results(res)
                d = {"physics": physics, "omega_pi": w, "alpha_deg": a, "seed": seed,
                     "probes": [[float(x) for x in row[:4]] + [bool(row[4])] for row in zip(
                         t.f_p_hz, t.a_p_deg, t.omega_b_deg_s, t.stderr_deg_s, t.unstable, strict=True)]}
                with cache.open("a") as fh:
                    fh.write(json.dumps(d) + "\n")
                have[key] = d
            out.append(have[key])
    return out


def read(d: dict, label: str) -> dict:
    from plate_env.core.probe_table import ProbeTable
    from plate_env.identify.estimators import make_estimator

    cols = list(zip(*d["probes"], strict=True))
    f, amp, y, se, u = (np.array(c, dtype=bool if i == 4 else float) for i, c in enumerate(cols))
    table = ProbeTable.from_arrays(f, amp, y, se, u)
    kw = {k: v.format(own=d["physics"]) if isinstance(v, str) else v for k, v in ESTIMATORS[label].items()}
    e = make_estimator(**kw).fit(table)
    truth = d["omega_pi"] * math.pi
    return {"physics": d["physics"], "omega_pi": d["omega_pi"], "alpha_deg": d["alpha_deg"], "estimator": label,
            "ok": e.ok, "estimate_pi": e.omega_n / math.pi if e.ok else None,
            "wrong": bool(e.ok and not e.omega_n_ci95[0] <= truth <= e.omega_n_ci95[1]),
            "bound": None if e.bound is None else [e.bound[0], e.bound[1] / math.pi],
            "bound_wrong": bool(e.bound is not None and (e.bound[0] == "above") != (truth > e.bound[1])),
            "reason": e.reason}


def table(rows: list[dict]) -> str:
    lines = ["| physics | estimator | outside: sweeps | estimate | 95 % excludes the truth | bound | bound on the "
             "wrong side | inside: sweeps | estimate |", "|---|---|---|---|---|---|---|---|---|"]
    for ph in dict.fromkeys(r["physics"] for r in rows):
        lo, hi = RANGE_PI[ph]
        for label in ESTIMATORS:
            r = [x for x in rows if x["physics"] == ph and x["estimator"] == label]
            out = [x for x in r if not lo <= x["omega_pi"] <= hi]
            ins = [x for x in r if lo <= x["omega_pi"] <= hi]
            wrong = ", ".join(f"{x['omega_pi']:g} pi a{x['alpha_deg']:g} -> {x['estimate_pi']:.3g} pi"
                              for x in out if x["ok"])
            lines.append(f"| {ph} | {label} | {len(out)} | {sum(x['ok'] for x in out)}"
                         f"{f' ({wrong})' if wrong else ''} | {sum(x['wrong'] for x in out)} | "
                         f"{sum(x['bound'] is not None for x in out)} | {sum(x['bound_wrong'] for x in r)} | "
                         f"{len(ins)} | {sum(x['ok'] for x in ins)} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--physics", default="pointmass,rigid_fast")
    ap.add_argument("--alphas", default="35,45,55", help="friction angles, deg")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", default="experiments/cache/out_of_range_sweeps.jsonl")
    ap.add_argument("--out", default=None, help="also write every reading here (JSON)")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", message=".*out of date.*")
    rows = []
    for ph in args.physics.split(","):
        for d in sweeps(ph, [float(a) for a in args.alphas.split(",")], args.seed, Path(args.cache)):
            rows += [read(d, label) for label in ESTIMATORS]
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1) + "\n")
    print(table(rows))


if __name__ == "__main__":
    main()
