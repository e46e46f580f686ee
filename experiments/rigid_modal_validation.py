"""Issue 34: the modal (floating-frame) rigid-tile disc against the converged rigid limit.

Same probes, scoring and speed harness as ``experiments/rigid_fast_validation.py`` (``common.compare`` and
``common.speed``):
every probe of ``experiments/results/rigid_reference.json`` (``rigid_limit`` at dt 6.25e-6 s), omega_B where both
are stable (median / max |relative difference|), stability agreement, first-hump f0; speed as x real time for one
probe and a batch of 32 with the point mass measured in the same run. The model
(:mod:`plate_env.physics.tilelink.rigid_modal`) is experimental and not a registered backend model.

Writes ``experiments/results/rigid_modal.json`` and ``.md`` (one run).
Usage: ``nice -n 10 python experiments/rigid_modal_validation.py [--routes a,b] [--repeats 1] [--merge]
[--no-batch-speed] [--yaw-offsets-mrad 0,1,2]``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import common
from common import compare, load_reference, spec_of, speed

import plate_env as pe
from plate_env.core.probe import SLIP_LIMIT_M
from plate_env.physics.tilelink.rigid_modal import ModalDiscConfig
from plate_env.physics.tilelink.rigid_modal_kernels import RigidModalPhysics

HERE = Path(__file__).resolve().parent

OUT = HERE / "results" / "rigid_modal"
#: Routes: (dt s, reduction, contact sweeps a step, what it stands for).
ROUTES = {
    "modal_nl10_2e-4": (2e-4, ModalDiscConfig(), 1,
                        "floating frame + modes < 200 Hz, stiffening in the 10 lowest out-of-plane modes (condensed), "
                        "foreshortening, dt 2e-4, one contact sweep"),
    "modal_nl10_1e-4": (1e-4, ModalDiscConfig(), 1, "the same at dt 1e-4"),
    "modal_linear_2e-4": (2e-4, ModalDiscConfig(n_nonlinear=0, foreshortening=False), 1,
                          "the linear floating frame (no stiffening, no foreshortening), dt 2e-4"),
    "modal_nl10_100hz_2e-4": (2e-4, ModalDiscConfig(cutoff_hz=100.0), 1,
                              "as modal_nl10_2e-4 with the cut-off at 100 Hz"),
    "modal_nl10_2e-4_it3": (2e-4, ModalDiscConfig(), 3, "as modal_nl10_2e-4 with 3 contact sweeps a step"),
    "modal_nl10_2e-4_it2": (2e-4, ModalDiscConfig(), 2, "as modal_nl10_2e-4 with 2 contact sweeps a step"),
    "modal_nl10_k40_2e-4": (2e-4, ModalDiscConfig(max_modes=40), 1,
                            "as modal_nl10_2e-4 with at most the 40 lowest modes dynamic"),
    "modal_nl10_k20_2e-4_it2": (2e-4, ModalDiscConfig(max_modes=20), 2,
                                "at most the 20 lowest modes dynamic (the rest static), 2 contact sweeps"),
    "modal_nl10_4e-4_it2": (4e-4, ModalDiscConfig(), 2, "as modal_nl10_2e-4_it2 at dt 4e-4"),
    "modal_nl10_4e-4_it3": (4e-4, ModalDiscConfig(), 3, "as modal_nl10_2e-4_it3 at dt 4e-4"),
    "modal_nl10_6e-4_it2": (6e-4, ModalDiscConfig(), 2, "as modal_nl10_2e-4_it2 at dt 6e-4"),
    # session h34d: the candidates of the notes, one at a time against modal_nl10_4e-4_it2
    # (modal_nl10_4e-4_it2_fsv, the foreshortening's velocity U ds/dt in the contact, ran at 1475ed7: its kernel
    # option was removed after, see rigid_modal_notes.md)
    "modal_nl10_400hz_4e-4_it2": (4e-4, ModalDiscConfig(cutoff_hz=400.0), 2,
                                  "as modal_nl10_4e-4_it2 with the cut-off at 400 Hz (more dynamic modes)"),
    "modal_nl10_1000hz_4e-4_it2": (4e-4, ModalDiscConfig(cutoff_hz=1000.0), 2,
                                   "as modal_nl10_4e-4_it2 with the cut-off at 1000 Hz (the truncated modes' "
                                   "flexibility mostly kept, quasi-statically: dt w ~ 2.5)"),
    "modal_nl10_4e-4_it4": (4e-4, ModalDiscConfig(), 4, "as modal_nl10_4e-4_it2 with 4 contact sweeps"),
    "modal_nl10_4e-4_it6": (4e-4, ModalDiscConfig(), 6, "as modal_nl10_4e-4_it2 with 6 contact sweeps"),
    "modal_nl5_4e-4_it2": (4e-4, ModalDiscConfig(n_nonlinear=5), 2,
                           "as modal_nl10_4e-4_it2 with the stiffening in the 5 lowest out-of-plane modes"),
    "modal_nl15_4e-4_it2": (4e-4, ModalDiscConfig(n_nonlinear=15), 2, "the same with 15"),
    "modal_nl20_4e-4_it2": (4e-4, ModalDiscConfig(n_nonlinear=20), 2, "the same with 20"),
    "modal_nl30_4e-4_it2": (4e-4, ModalDiscConfig(n_nonlinear=30), 2,
                            "the same with 30 (converged: 50 and all 71 give the same 10pi sweep within ~1 %)"),
    "modal_nl30_1e-4_it2": (1e-4, ModalDiscConfig(n_nonlinear=30), 2, "modal_nl30_4e-4_it2 at dt 1e-4"),
    "modal_nl30_2000hz_2e-4_it2": (2e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                   "30 nonlinear modes, every mode below 2 kHz dynamic (the held rows' in-plane "
                                   "modes from ~400 Hz up resolved in time, not condensed), dt 2e-4"),
    "modal_nl30_2000hz_1e-4_it2": (1e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                   "modal_nl30_2000hz_2e-4_it2 at dt 1e-4"),
    # session h34e: the exact modal propagator (integrator="exact": each mode's 2x2 state-transition matrix and
    # constant-force response, stiffening and contact held constant over the step) instead of backward Euler
    "modal_nl30_2000hz_2e-4_it2_exp": (2e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                       "modal_nl30_2000hz_2e-4_it2 with the exact modal propagator"),
    "modal_nl30_2000hz_4e-4_it2_exp": (4e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                       "modal_nl30_2000hz_2e-4_it2_exp at dt 4e-4 (modes above 1250 Hz: w dt > pi)"),
    "modal_nl30_1000hz_4e-4_it2_exp": (4e-4, ModalDiscConfig(cutoff_hz=1000.0, n_nonlinear=30), 2,
                                       "every mode below 1 kHz dynamic, 30 nonlinear, exact propagator, dt 4e-4"),
    "modal_nl10_2000hz_4e-4_it2_exp": (4e-4, ModalDiscConfig(cutoff_hz=2000.0), 2,
                                       "every mode below 2 kHz dynamic, 10 nonlinear, exact propagator, dt 4e-4"),
    "modal_nl10_4e-4_it2_exp": (4e-4, ModalDiscConfig(), 2,
                                "the default reduction (modes < 200 Hz, 10 nonlinear) with the exact propagator"),
    "modal_nl30_2000hz_2e-4_it2_kick": (2e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                        "modal_nl30_2000hz_2e-4_it2_exp with the contact impulse moving the modes as "
                                        "the frame's symplectic-Euler kick (dq = dt dv; integrator exact_kick)"),
    "modal_nl30_2000hz_4e-4_it2_kick": (4e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                        "modal_nl30_2000hz_2e-4_it2_kick at dt 4e-4"),
    "modal_nl30_2000hz_4e-4_it2": (4e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                   "modal_nl30_2000hz_2e-4_it2 (backward Euler) at dt 4e-4: the same step as the "
                                   "exact propagator's"),
    # session 2026-12-04 evening: the faithful route's step limit (does it converge to the reference's calls?)
    "modal_nl30_2000hz_5e-5_it2": (5e-5, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2,
                                   "modal_nl30_2000hz_1e-4_it2 at dt 5e-5: the faithful route's limit in its step"),
    "rigid_fast": (None, None, None, "the shipped model=\"rigid_fast\" (maximal coordinates, dt 2.5e-5): the "
                   "spread of its calls over the initial yaw, beside the modal routes' (no speed here: "
                   "rigid_fast.md)"),
}


def physics_of(name: str, slip_limit: float = SLIP_LIMIT_M):
    """The physics of a route: the modal disc, or the shipped rigid_fast for the ``rigid_fast`` row; ``slip_limit``
    m, the centre distance that ends a probe as slipped (the paper's 10 mm)."""
    dt, cfg, iters, _ = ROUTES[name]
    if cfg is None:
        return pe.make_physics("tilelink", model="rigid_fast", slip_limit=slip_limit)
    integrator = {"_exp": "exact", "_kick": "exact_kick"}.get(name[name.rfind("_"):], "backward_euler")
    return RigidModalPhysics(dt, cfg, iters, slip_limit=slip_limit, integrator=integrator)


def spread(rows: list[dict], physics, offsets_mrad: list[float]) -> list[dict]:
    """The route's summary at each initial-yaw offset (mrad) added to every probe: how much of the scores is the
    model's sensitivity to its placement (the converged reference's own calls do not move over 0.5-3 mrad:
    ``results/rigid_reference_spread.md``)."""
    out = []
    for off in offsets_mrad:
        specs = [replace(spec_of(r), initial_yaw=r["initial_yaw_rad"] + 1e-3 * off) for r in rows]
        res = physics.run(specs)
        s_ = compare(rows, res)["summary"]
        out.append({"yaw_offset_mrad": off, **{k: s_[k] for k in ("n_both_stable", "median_abs_rel", "max_abs_rel",
                                                                  "stability_agreement", "max_abs_f0_diff_hz",
                                                                  "n_fits_compared")},
                    "disagree": [r["key"] for r, x in zip(rows, res, strict=True) if r["unstable"] != x.unstable]})
    return out


def cpu_speed(physics, pointmass, with_batch: bool = True) -> dict:
    """Real-time factors by CPU time of this process (the kernel's own cost on a loaded shared machine, where
    wall time measures the other jobs too): the cheese at 20 Hz alone, and a 32-probe batch (summed over its
    threads), the point mass beside it (:func:`common.speed` on ``time.process_time``, one timed run each)."""
    done = speed(physics, pointmass, 1, clock=time.process_time, batch=with_batch)
    labels = {"one_probe_rtf": "one_probe_cpu_rtf", "batch32_rtf": "batch32_cpu_rtf_per_core"}
    return {name: {labels[k]: v for k, v in done[name].items() if k in labels} for name in ("route", "pointmass")}


def _spread_cell(sp: list[dict] | None) -> str:
    if not sp:
        return "-"

    def rng(key: str, scale: float = 100.0) -> str:
        v = [scale * x[key] for x in sp]
        return f"{min(v):.1f}-{max(v):.1f}" if key != "stability_agreement" else f"{min(v):.0f}-{max(v):.0f}"

    offs = "/".join(f"{x['yaw_offset_mrad']:g}" for x in sp)
    return (f"{rng('median_abs_rel')} % / {rng('max_abs_rel')} % / {rng('stability_agreement')} % "
            f"(+{offs} mrad)")


def render(report: dict) -> str:
    """The markdown report of the routes run so far."""
    lines = ["# Issue 34: the modal (floating-frame) rigid-tile disc against the rigid limit", "",
             f"Reference: `rigid_limit` at dt {report['reference_dt']:g} s, {report['n_reference']} probes "
             "(experiments/results/rigid_reference.json). Written by `python experiments/rigid_modal_validation.py` "
             "(one run per route). Model: `plate_env/physics/tilelink/rigid_modal.py` (experimental, unregistered; "
             "design: rigid_modal_notes.md).",
             "Tolerances (issue 34): omega_B 2 % median / 5 % max where both are stable, stability calls agree "
             ">= 90 %, first-hump f0 within 0.3 Hz; speed >= 10x one probe, >= 25x a batch of 32 (2 cores).", "",
             "Last column: the same scores with the initial yaw of every probe moved by the listed offsets (mrad): "
             "median / max / agreement as min-max over the offsets (runs of session h34d on).", "",
             "| route | dt (s) | both stable | median / max abs diff | stability agree | max abs df0 (Hz) | "
             "one probe x real time, CPU (point mass) | batch 32 x real time, wall (point mass) | load | "
             "over initial yaw: median / max / agree |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in report["routes"].items():
        s_, cs, sp = r["compare"]["summary"], r.get("cpu_speed") or {}, r.get("speed")
        one = (f"{cs['route']['one_probe_cpu_rtf']:.1f} ({cs['pointmass']['one_probe_cpu_rtf']:.1f})"
               if cs else "-")
        bat = (f"{sp['route']['batch32_rtf']:.1f} ({sp['pointmass']['batch32_rtf']:.1f})" if sp else "not run")
        load = f"{sp['load_avg_1min']:.1f}" if sp else f"{r.get('load_avg_1min', float('nan')):.1f}"
        dt_ = f"{r['dt']:g}" if r["dt"] else "2.5e-05"
        lines.append(f"| {name} | {dt_} | {s_['n_both_stable']} | {100 * s_['median_abs_rel']:.1f} % / "
                     f"{100 * s_['max_abs_rel']:.1f} % | {100 * s_['stability_agreement']:.0f} % | "
                     f"{s_['max_abs_f0_diff_hz']:.2f} ({s_['n_fits_compared']} of {s_['n_fits_reference']} fits) | "
                     f"{one} | {bat} | {load} | {_spread_cell(r.get('spread'))} |")
    lines += ["", "Routes:", ""] + [f"- {n}: {r['what']} (at {r['commit']})" for n, r in report["routes"].items()]
    for name, r in report["routes"].items():
        probes = r["compare"]["probes"]
        off = [p for p in probes if p["ref_unstable"] != p["new_unstable"]]
        worst = sorted((p for p in probes if not p["ref_unstable"] and not p["new_unstable"]),
                       key=lambda p: -abs(p["new"] - p["ref"]) / abs(p["ref"]))[:6]
        lines += ["", f"## {name}", "", "Stability calls that differ (reference -> route): " + (", ".join(
            f"{p['key']} ({'unstable' if p['ref_unstable'] else 'stable'} -> {p['new_reason'] or 'stable'})"
            for p in off) or "none") + ".", "", "Largest differences (reference -> route, deg/s): " + ", ".join(
            f"{p['key']} {p['ref']:.1f} -> {p['new']:.1f} ({100 * (p['new'] - p['ref']) / abs(p['ref']):+.1f} %)"
            for p in worst) + ".", "", "First-hump fits f0 (Hz), reference -> route: " + (", ".join(
                f"{k} {v['f0_hz']:.2f} -> " + (f"{r['compare']['fits_route'][k]['f0_hz']:.2f}"
                                               if "f0_hz" in r["compare"]["fits_route"].get(k, {}) else "no fit")
                for k, v in r["compare"]["fits_reference"].items() if "f0_hz" in v) or "none") + "."]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--routes", default=",".join(ROUTES), help="comma-separated subset of " + ", ".join(ROUTES))
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--merge", action="store_true", help="keep the other routes of an earlier run's JSON")
    ap.add_argument("--no-batch-speed", action="store_true",
                    help="measure speed on one probe only (CPU time), not the wall-time harness and the batch of 32 "
                         "(32 objects to build: minutes on a loaded machine)")
    ap.add_argument("--yaw-offsets-mrad", default="",
                    help="also score each route with every probe's initial yaw moved by these offsets, e.g. 0,1,2")
    args = ap.parse_args()
    offsets = [float(x) for x in args.yaw_offsets_mrad.split(",") if x.strip()]
    rows = load_reference()
    specs = [spec_of(r) for r in rows]
    report = {"reference_dt": rows[0]["dt_s"], "n_reference": len(rows), "routes": {}}
    if args.merge and OUT.with_suffix(".json").exists():
        report = json.loads(OUT.with_suffix(".json").read_text())
    pointmass = pe.make_physics("tilelink")
    for name in args.routes.split(","):
        dt, cfg, iters, what = ROUTES[name]
        physics = physics_of(name)
        physics.run(specs[:2])  # compile outside the timing
        t0 = time.perf_counter()
        results = physics.run(specs)
        cmp_ = compare(rows, results)
        report["routes"][name] = {"dt": dt, "what": what, "compare": cmp_, "sweep_wall_s": time.perf_counter() - t0,
                                  "speed": (None if args.no_batch_speed or cfg is None
                                            else speed(physics, pointmass, args.repeats)),
                                  "cpu_speed": None if cfg is None else cpu_speed(physics, pointmass,
                                                                                   not args.no_batch_speed),
                                  "spread": spread(rows, physics, offsets) if offsets else None,
                                  "commit": common.git_commit(under="plate_env"), "load_avg_1min": os.getloadavg()[0]}
        print(name, json.dumps(cmp_["summary"]), json.dumps(report["routes"][name]["speed"]),
              json.dumps(report["routes"][name]["cpu_speed"]), flush=True)
        OUT.with_suffix(".json").write_text(json.dumps(report, indent=1) + "\n")
        OUT.with_suffix(".md").write_text(render(report))
    print(render(report))


if __name__ == "__main__":
    main()
