"""Issue 26: fast routes to the rigid-tile model's rigid limit, measured against the converged reference.

For each route (a rigid-tile kernel setting; ``ROUTES``) this runs every probe of
``experiments/results/rigid_reference.json`` (the `rigid_limit` model at dt = 6.25e-6 s, written by
``experiments/rigid_reference.py``) with the same placement and windows, and reports:

* omega_B against the reference where both are stable (median and max |relative difference|);
* how often the two stability calls agree;
* the package's first-hump Lorentzian fit (``plate_env.fitting.fit_lorentzian``) of each object's sweep, f0 against
  the reference's;
* speed with the point mass's harness (``experiments/bench_physics.py``: the cheese at 20 Hz alone, a batch of 32
  objects 5pi-36pi at 18-21 Hz), the point mass measured in the same run for the ratio, and the load (``uptime``);
* for the routes not built as kernels, the structural numbers that decide them (``structure``).

Writes ``experiments/results/rigid_fast.json`` and ``.md`` from one run.
Usage: ``nice -n 5 python experiments/rigid_fast_validation.py [--routes small_steps,...] [--repeats 3]``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import common
from common import compare, load_reference, spec_of, speed

import plate_env as pe
from plate_env.physics.tilelink.rigid import RIGID_FAST_CONFIG, RigidTileConfig

HERE = Path(__file__).resolve().parent

OUT = HERE / "results" / "rigid_fast"
#: Routes measured: (tilelink model, dt s, joint/solver config, what it stands for).
ROUTES = {
    "small_steps": ("rigid_fast", 2.5e-5, RIGID_FAST_CONFIG,
                    "the rigid limit's rows (40000 rad/s) as compliant constraints, one Gauss-Seidel sweep per small "
                    "step (velocity-level XPBD); the shipped model=\"rigid_fast\""),
    "small_steps_5e-5": ("rigid_fast", 5e-5, RigidTileConfig(omega_rigid=20000.0, iterations=1),
                         "the same at twice the step (rows at 20000 rad/s: 40000 runs away at 5e-5 s)"),
    "exact_joint_solve_1e-4": ("rigid", 1e-4, RigidTileConfig(omega_rigid=20000.0, iterations=8),
                               "the joint system solved to convergence each step (8 sweeps; the accuracy an exact "
                               "sparse solve reaches at dt 1e-4 s; its cost: structure)"),
    "rigid_2e-4": ("rigid", 2e-4, RigidTileConfig(), "the shipped model=\"rigid\" (5000 rad/s rows) for comparison"),
}


def physics_of(route: str):
    model, dt, cfg, _ = ROUTES[route]
    return pe.make_physics("tilelink", model=model, dt=dt, rigid_config=cfg)


def structure() -> dict:
    """Numbers that decide the routes not built as kernels: ``python experiments/rigid_fast_structure.py`` run in its
    own process (it prints them as JSON)."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, str(HERE / "rigid_fast_structure.py")], capture_output=True, text=True,
                          check=True)
    return json.loads(done.stdout)


def _fit_cell(d: dict) -> str:
    if "f0_hz" in d:
        return f"{d['f0_hz']:.2f} / {d['b_hz']:.2f} / {d['omega_max_deg_s']:.0f}"
    return f"no fit ({d.get('reason', 'missing')[:60]})"


def markdown(report: dict) -> str:
    lines = ["# Issue 26: fast routes to the rigid limit", "",
             f"Reference: `rigid_limit` at dt {report['reference_dt']:g} s, {report['n_reference']} probes "
             "(experiments/results/rigid_reference.json). Written by `python experiments/rigid_fast_validation.py`.",
             "Tolerances: omega_B 2 % median / 5 % max where both are stable, stability calls agree >= 90 %, "
             "first-hump f0 within 0.3 Hz; speed >= 10x one probe, >= 25x a batch of 32 (2 cores).", "",
             "| route | dt (s) | both stable | median / max abs diff | stability agree | max abs df0 (Hz) | "
             "one probe rtf (point mass) | batch 32 rtf (point mass) | load |", "|---|---|---|---|---|---|---|---|---|"]
    for name, r in report["routes"].items():
        s, sp = r["compare"]["summary"], r["speed"]
        lines.append(f"| {name} | {r['dt']:g} | {s['n_both_stable']} | {100 * s['median_abs_rel']:.1f} % / "
                     f"{100 * s['max_abs_rel']:.1f} % | {100 * s['stability_agreement']:.0f} % | "
                     f"{s['max_abs_f0_diff_hz']:.2f} ({s['n_fits_compared']} of {s['n_fits_reference']} fits; "
                     f"{s['n_sweeps']} sweeps) | "
                     f"{sp['route']['one_probe_rtf']:.2f} ({sp['pointmass']['one_probe_rtf']:.1f}) | "
                     f"{sp['route']['batch32_rtf']:.2f} ({sp['pointmass']['batch32_rtf']:.1f}) | "
                     f"{sp['load_avg_1min']:.1f} |")
    lines += ["", "Routes:", ""] + [f"- {n}: {r['what']}" + (f" (kernel at {r['commit']})" if r.get("commit") else "")
                                     for n, r in report["routes"].items()]
    lines += ["", "Speed as a share of the point mass's in the same run (its real-time factors on a quiet machine: "
              "experiments/results/bench_physics.md): " + "; ".join(
                  f"{n} {r['speed']['route']['one_probe_rtf'] / r['speed']['pointmass']['one_probe_rtf']:.3f} (one) / "
                  f"{r['speed']['route']['batch32_rtf'] / r['speed']['pointmass']['batch32_rtf']:.3f} (batch)"
                  for n, r in report["routes"].items())]
    for name, r in report["routes"].items():
        s = r["compare"]["summary"]
        off = [p for p in r["compare"]["probes"] if p["ref_unstable"] != p["new_unstable"]]
        lines += ["", f"## {name}", "", f"What holds: {s['holds']} / speed {r['speed']['holds']}.", "",
                  "Stability calls that differ (reference -> route): " + (", ".join(
                      f"{p['key']} ({'unstable' if p['ref_unstable'] else 'stable'} -> "
                      f"{p['new_reason'] or 'stable'})" for p in off) or "none") + ".", "",
                  "First-hump fits (f0 Hz / b Hz / omega_max deg/s), reference -> route:", ""]
        for k, ref in r["compare"]["fits_reference"].items():
            new = r["compare"]["fits_route"].get(k, {})
            lines.append(f"- {k}: {_fit_cell(ref)} -> {_fit_cell(new)}")
    if report.get("structure"):
        lines += ["", "## Structure of the routes not built as kernels", "", "```",
                  json.dumps(report["structure"], indent=1), "```"]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--routes", default=",".join(ROUTES), help="comma-separated subset of " + ", ".join(ROUTES))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-structure", action="store_true")
    ap.add_argument("--merge", action="store_true",
                    help="keep the other routes (and the structure section) of the JSON of an earlier run, replacing "
                         "only the routes run now")
    ap.add_argument("--speed-only", action="store_true",
                    help="with --merge: measure only the speed of the routes, keeping their comparison from the JSON")
    ap.add_argument("--render-only", action="store_true",
                    help="rewrite the markdown (and the structure section) from the JSON of an earlier run")
    args = ap.parse_args()
    if args.render_only:
        report = json.loads(OUT.with_suffix(".json").read_text())
        if not args.no_structure:
            report["structure"] = structure()
        OUT.with_suffix(".json").write_text(json.dumps(report, indent=1) + "\n")
        OUT.with_suffix(".md").write_text(markdown(report))
        print(markdown(report))
        return
    rows = load_reference()
    specs = [spec_of(r) for r in rows]
    report = {"reference_dt": rows[0]["dt_s"], "n_reference": len(rows), "routes": {}}
    if args.merge:
        report = json.loads(OUT.with_suffix(".json").read_text())
    pointmass = pe.make_physics("tilelink")
    for name in args.routes.split(","):
        physics = physics_of(name)
        if args.speed_only:
            report["routes"][name].update(speed=speed(physics, pointmass, args.repeats),
                                          commit=common.git_commit(under="plate_env"))
            print(name, json.dumps(report["routes"][name]["speed"]), flush=True)
            continue
        t0 = time.perf_counter()
        results = physics.run(specs)
        cmp_ = compare(rows, results)
        report["routes"][name] = {"dt": ROUTES[name][1], "what": ROUTES[name][3], "compare": cmp_,
                                  "sweep_wall_s": time.perf_counter() - t0,
                                  "speed": speed(physics, pointmass, args.repeats),
                                  "commit": common.git_commit(under="plate_env")}
        print(name, json.dumps(cmp_["summary"]), json.dumps(report["routes"][name]["speed"]), flush=True)
        OUT.with_suffix(".json").write_text(json.dumps(report, indent=1) + "\n")
    if not args.no_structure:
        report["structure"] = structure()
    OUT.with_suffix(".json").write_text(json.dumps(report, indent=1) + "\n")
    OUT.with_suffix(".md").write_text(markdown(report))
    print(markdown(report))


if __name__ == "__main__":
    main()
