"""Issue 37: readings of data of unknown origin, the rule that decides when they stand, measured on the same sweeps.

    python experiments/unknown_origin_rule.py [--out experiments/results/unknown_origin_rule.json] [--limit N]

Every estimator a user reaches on a lab's sweep whose physics is unknown (the paper's calibration, the lab's and the
paper's Eq. (10) lines, the ``lab`` pool's atlas reading) reads each sweep once with no unknown-origin rule; every
shipped physics states once where it places the disc (:func:`plate_env.identify.unknown_origin.physics_readings`);
then each rule decides, so the rules are scored on identical readings: ``none`` (no rule: the readings as their gates
leave them), ``every`` (shipped, :func:`plate_env.identify.unknown_origin.every_rule`), ``union`` (no estimate as soon
as some explaining physics places the disc beyond its range, with the bound true under all of them) and ``best`` (the
explaining physics of highest predictive p-value decides alone).

Sweeps (all cached, nothing simulated): the out-of-range study's (``experiments/cache/out_of_range_sweeps.jsonl``:
point mass and rigid tiles at 0.3-1.2 and 50-200 pi, outside every model's range, and 3, 10, 30 pi), and the
in-range evaluation sets of every shipped physics (``plate_env.build.eq10.LAB_SETS``: 120 point-mass discs each with
its own joint/contact draw, 20 rigid-limit discs, 24 PyBullet discs; and 20 ``rigid_fast`` discs, the faithful
physics, s700). Outside the range (1.4-45 pi): estimates (wrong: 95 % interval excluding the truth), bounds (wrong
side). Inside: estimates kept, median error, 95 % coverage, bounds and those on the wrong side. Prints markdown.
"""

from __future__ import annotations

import argparse
import json
import math
import warnings
from pathlib import Path

import numpy as np

ESTIMATORS = {"calibrated paper": dict(calibration="paper"),
              "lorentz lab": dict(method="lorentz", name="lab/lab"),
              "lorentz paper": dict(method="lorentz", name="paper/pointmass"),
              "atlas lab": dict(method="atlas", name="tilelink/pointmass", forward="lab")}
RANGE_PI = (1.4, 45.0)
ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "experiments" / "cache"


def sets() -> list[tuple[str, float, object]]:
    """(set label, omega_n rad/s, ProbeTable) of every sweep read."""
    from plate_env.build.eq10 import LAB_SETS, RIGID_FAST, lab_backend_of
    from plate_env.build.eval_sets import EvalSet, run_eval_set
    from plate_env.core.probe_table import ProbeTable

    out = []
    for line in (CACHE / "out_of_range_sweeps.jsonl").read_text().splitlines():
        d = json.loads(line)
        cols = list(zip(*d["probes"], strict=True))
        t = ProbeTable.from_arrays(*[np.array(c, dtype=bool if i == 4 else float) for i, c in enumerate(cols)])
        out.append((f"study {d['physics']}", d["omega_pi"] * math.pi, t))
    fams = dict(LAB_SETS, rigid_fast=EvalSet("tilelink_rigid_fast", 20, 700, (3.0,)))
    for fam, es in fams.items():
        backend = (lambda _n: RIGID_FAST) if fam == "rigid_fast" else lab_backend_of(fam)
        tables = run_eval_set(es, backend, None, cache_dir=CACHE)[es.a_p_deg[0]]
        out += [(f"eval {fam}", o.omega_n, t) for o, t in zip(es.objects(), tables, strict=True)]
    return out


def support(r) -> tuple[float, float]:
    """The omega_n (rad/s) a PhysicsReading allows, as an interval (0 and inf open ends)."""
    if r.kind == "inside":
        return r.ci95
    if r.bound is not None:
        return (r.bound[1], math.inf) if r.bound[0] == "above" else (0.0, r.bound[1])
    return (0.0, math.inf)


def union_rule(readings):
    """The rule measured against the shipped one: no estimate as soon as some physics that explains the probes
    places the disc beyond its range, with the bound true under every explaining physics (the union of their
    supports), or none."""
    from plate_env.identify.unknown_origin import Verdict

    said = [r for r in readings if r.explains]
    if not any(r.kind == "beyond" for r in said):
        return None
    lo, hi = min(support(r)[0] for r in said), max(support(r)[1] for r in said)
    bound = ("above", lo) if lo > 0 and math.isinf(hi) else ("below", hi) if lo == 0 and math.isfinite(hi) else None
    return Verdict("some physics places it beyond", bound)


def score(rows: list[dict]) -> str:
    head = ("| sweeps | estimator | rule | outside: n | estimates (wrong) | bounds (wrong side) | inside: n | "
            "estimates | median error | 95 % coverage | bounds (wrong side) |\n" + "|---" * 11 + "|")
    lines = [head]
    keys = sorted({(r["set"], r["estimator"]) for r in rows})
    for s, e in keys:
        for rule in ("none", "every", "union", "best"):
            rr = [r for r in rows if (r["set"], r["estimator"]) == (s, e)]
            out = [r[rule] for r in rr if not r["inside"]]
            ins = [r[rule] for r in rr if r["inside"]]
            err = [a["error"] for a in ins if a["ok"]]
            cov = [a["covers"] for a in ins if a["ok"]]

            def b(a):
                return f"{sum(x['bound'] is not None for x in a)} ({sum(x['bound_wrong'] for x in a)})"
            lines.append(f"| {s} | {e} | {rule} | {len(out)} | {sum(a['ok'] for a in out)} "
                         f"({sum(a['ok'] and not a['covers'] for a in out)}) | {b(out)} | {len(ins)} | "
                         f"{sum(a['ok'] for a in ins)} | {f'{100 * np.median(err):.1f} %' if err else '-'} | "
                         f"{f'{np.mean(cov):.2f}' if cov else '-'} | {b(ins)} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=None, help="also write every reading here (JSON)")
    ap.add_argument("--limit", type=int, default=None, help="at most this many sweeps per set (a quick look)")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    import plate_env.identify.unknown_origin as uo
    from plate_env.identify.estimators import make_estimator
    from plate_env.surrogate.conditioning import KnownInputs

    uo.RULE = lambda readings: None  # the raw readings; the rules are applied below
    def best_rule(readings):  # the explaining physics whose check p-value is highest decides alone
        said = [r for r in readings if r.explains]
        return union_rule([max(said, key=lambda r: r.p_value or 0.0)]) if said else None

    rules = {"none": lambda readings: None, "every": uo.every_rule, "union": union_rule, "best": best_rule}
    ests = {k: make_estimator(**v) for k, v in ESTIMATORS.items()}
    seen: dict[str, int] = {}
    rows = []
    for label, truth, t in sets():
        seen[label] = seen.get(label, 0) + 1
        if args.limit is not None and seen[label] > args.limit:
            continue
        readings = uo.physics_readings(t, KnownInputs())
        verdicts = {k: r(readings) for k, r in rules.items()}
        inside = RANGE_PI[0] <= truth / math.pi <= RANGE_PI[1]
        for name, est in ests.items():
            e = est.fit(t)
            row = {"set": label, "omega_pi": truth / math.pi, "estimator": name, "inside": inside,
                   "physics": [[r.name, r.kind, r.bound and [r.bound[0], r.bound[1] / math.pi],
                                r.ci95 and [x / math.pi for x in r.ci95], r.p_value] for r in readings]}
            for k, v in verdicts.items():
                ok = e.ok and v is None
                bound = e.bound if not e.ok else (v.bound if v is not None else None)
                row[k] = {"ok": ok, "estimate_pi": e.omega_n / math.pi if ok else None,
                          "error": abs(e.omega_n - truth) / truth if ok else None,
                          "covers": bool(ok and e.omega_n_ci95[0] <= truth <= e.omega_n_ci95[1]),
                          "bound": None if bound is None else [bound[0], bound[1] / math.pi],
                          "bound_wrong": bool(bound is not None and (bound[0] == "above") != (truth > bound[1]))}
            rows.append(row)
        print(f"{label} {truth / math.pi:.3g} pi: " + ", ".join(f"{r.name.split('/')[1]} {r.kind}" for r in readings),
              flush=True)
    print(score(rows))
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
