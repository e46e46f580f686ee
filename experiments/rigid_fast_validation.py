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
import math
import os
import time
from pathlib import Path

import numpy as np
from common import rtf

import plate_env as pe
from plate_env.core.probe import ProbeSpec
from plate_env.identify.fitting import fit_lorentzian
from plate_env.physics.tilelink.rigid import RIGID_FAST_CONFIG, RigidTileConfig

HERE = Path(__file__).resolve().parent

REFERENCE = HERE / "results" / "rigid_reference.json"
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
TOL_MEDIAN, TOL_MAX, TOL_AGREE, TOL_F0 = 0.02, 0.05, 0.90, 0.3


def load_reference() -> list[dict]:
    return json.loads(REFERENCE.read_text())["probes"]


def spec_of(row: dict) -> ProbeSpec:
    """The reference probe exactly as it was run (object, motion, windows, placement)."""
    obj = pe.ObjectSpec.from_paper(row["omega_n_pi"], row["alpha_deg"])
    mot = pe.PlateMotion.from_paper(row["f_p_hz"], row["a_p_deg"], row["b_p_mm"])
    return ProbeSpec(obj=obj, motion=mot, settle_s=row["settle_s"], measure_s=row["measure_s"],
                     initial_yaw=row["initial_yaw_rad"], initial_offset=tuple(row["initial_offset_m"]))


def physics_of(route: str):
    model, dt, cfg, _ = ROUTES[route]
    return pe.make_physics("tilelink", model=model, dt=dt, rigid_config=cfg)


def fits(rows: list[dict], omegas: list[float], unstable: list[bool]) -> dict[str, dict]:
    """First-hump fit per object (omega_n, alpha): f0, b, omega_max or the reason it cannot fit."""
    out = {}
    for key in sorted({(r["omega_n_pi"], r["alpha_deg"]) for r in rows}):
        idx = [i for i, r in enumerate(rows) if (r["omega_n_pi"], r["alpha_deg"]) == key]
        if len(idx) < 4:
            continue
        res = fit_lorentzian([rows[i]["f_p_hz"] for i in idx], [omegas[i] for i in idx],
                             unstable=[unstable[i] for i in idx])
        name = f"{key[0]:g}pi_{key[1]:g}deg"
        out[name] = ({"f0_hz": res.f0, "b_hz": res.b, "omega_max_deg_s": res.omega_max, "n_used": res.n_used}
                     if res.ok else {"reason": res.reason})
    return out


def compare(rows: list[dict], results) -> dict:
    """omega_B differences where both are stable, stability agreement, fits of both, per-probe rows."""
    ref_w = [r["omega_b_deg_s"] for r in rows]
    ref_u = [r["unstable"] for r in rows]
    new_w = [r.omega_b_deg_s for r in results]
    new_u = [r.unstable for r in results]
    rel = [(n - w) / abs(w) for w, u, n, v in zip(ref_w, ref_u, new_w, new_u, strict=True)
           if not u and not v and abs(w) > 0]
    agree = float(np.mean([u == v for u, v in zip(ref_u, new_u, strict=True)]))
    ref_fit, new_fit = fits(rows, ref_w, ref_u), fits(rows, new_w, new_u)
    ref_ok = [k for k in ref_fit if "f0_hz" in ref_fit[k]]
    df0 = {k: new_fit[k]["f0_hz"] - ref_fit[k]["f0_hz"] for k in ref_ok if "f0_hz" in new_fit.get(k, {})}
    arel = np.abs(rel) if rel else np.array([math.nan])
    summary = {"n_probes": len(rows), "n_both_stable": len(rel), "median_abs_rel": float(np.median(arel)),
               "max_abs_rel": float(np.max(arel)), "stability_agreement": agree, "f0_diff_hz": df0,
               "max_abs_f0_diff_hz": max((abs(v) for v in df0.values()), default=math.nan),
               "n_fits_compared": len(df0), "n_fits_reference": len(ref_ok),
               "n_sweeps": len(ref_fit)}
    summary["holds"] = {
        "omega_b_median": summary["median_abs_rel"] <= TOL_MEDIAN, "omega_b_max": summary["max_abs_rel"] <= TOL_MAX,
        "stability_agreement": agree >= TOL_AGREE,
        "fits": len(df0) == len(ref_ok) > 0 and summary["max_abs_f0_diff_hz"] <= TOL_F0}
    probes = [{"key": r["key"], "ref": w, "ref_unstable": u, "new": n, "new_unstable": v, "new_reason": x.reason}
              for r, w, u, n, v, x in zip(rows, ref_w, ref_u, new_w, new_u, results, strict=True)]
    return {"summary": summary, "fits_reference": ref_fit, "fits_route": new_fit, "probes": probes}


def speed(physics, pointmass, repeats: int) -> dict:
    """Real-time factors with bench_physics' harness, the point mass in the same run."""
    cheese = pe.preset("cheese")
    one = [ProbeSpec(cheese, pe.PlateMotion.from_paper(20.0, 3.0))]
    batch = [ProbeSpec(cheese.with_(omega_n=(5 + k) * math.pi), pe.PlateMotion.from_paper(18 + 0.1 * k, 3.0))
             for k in range(32)]
    out = {}
    for name, phys in (("route", physics), ("pointmass", pointmass)):
        r1, _ = rtf(phys, one, repeats)
        r32, bad = rtf(phys, batch, repeats)
        out[name] = {"one_probe_rtf": r1, "batch32_rtf": r32, "batch32_unstable": bad}
    out["load_avg_1min"] = os.getloadavg()[0]
    out["holds"] = {"one_probe": out["route"]["one_probe_rtf"] >= 10.0, "batch32": out["route"]["batch32_rtf"] >= 25.0}
    return out


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


def _commit() -> str:
    """The worktree's commit (with ``+dirty`` when the package has uncommitted changes): which kernel a route was
    run on."""
    import subprocess

    def git(*a):
        return subprocess.run(["git", *a], cwd=HERE, capture_output=True, text=True).stdout.strip()

    dirty = git("status", "--porcelain", "--untracked-files=no", "--", str(HERE.parent / "plate_env"))
    return git("rev-parse", "--short", "HEAD") + ("+dirty" if dirty else "")


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
            report["routes"][name].update(speed=speed(physics, pointmass, args.repeats), commit=_commit())
            print(name, json.dumps(report["routes"][name]["speed"]), flush=True)
            continue
        t0 = time.perf_counter()
        results = physics.run(specs)
        cmp_ = compare(rows, results)
        report["routes"][name] = {"dt": ROUTES[name][1], "what": ROUTES[name][3], "compare": cmp_,
                                  "sweep_wall_s": time.perf_counter() - t0,
                                  "speed": speed(physics, pointmass, args.repeats), "commit": _commit()}
        print(name, json.dumps(cmp_["summary"]), json.dumps(report["routes"][name]["speed"]), flush=True)
        OUT.with_suffix(".json").write_text(json.dumps(report, indent=1) + "\n")
    if not args.no_structure:
        report["structure"] = structure()
    OUT.with_suffix(".json").write_text(json.dumps(report, indent=1) + "\n")
    OUT.with_suffix(".md").write_text(markdown(report))
    print(markdown(report))


if __name__ == "__main__":
    main()
