"""Point-mass vs rigid-tile tile-link models: first-hump Lorentzian fits, omega_B differences, speed.

Sweeps the plate frequency f_p at A_p = 3 deg, B_p = 3 mm for several objects (omega_n, alpha), runs every probe
with the point-mass model (``plate_env.make_physics("tilelink")``) and with the rigid-tile model
(:func:`plate_env.physics.tilelink.rigid_kernels.run_rigid_arrays`), fits Eq. (9) of the paper to the stable
probes up to the first dip after the first hump, and writes ``experiments/results/bench_models.md`` and the fits,
slopes and speeds in ``bench_models.json`` beside it (the source of docs/physics.md's table).

Usage: ``python experiments/bench_models.py [--quick]``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import plate_env as pe
from plate_env.core.probe import ProbeSpec, Status
from plate_env.identify.fitting import fit_lorentzian
from plate_env.physics.tilelink import rigid_kernels as rk
from plate_env.physics.tilelink.params import DEFAULT_DT, P_RECEVERY

RESULTS = Path(__file__).resolve().parent / "results" / "bench_models.md"
PAPER = {(10.0, 36.9): (25.1, 5.1, 598.7), (33.0, 36.9): (28.2, 5.8, 746.9), (10.0, 56.3): (24.6, 5.8, 520.9)}


def fit(freqs: np.ndarray, omegas: np.ndarray, unstable: np.ndarray) -> tuple[float, float, float, int]:
    """(f0 Hz, b Hz, omega_max deg/s, points used) of the package's first-hump fit; NaNs if it cannot fit."""
    res = fit_lorentzian(freqs, omegas, unstable=unstable)
    if not res.ok:
        return math.nan, math.nan, math.nan, res.n_used
    return res.f0, res.b, res.omega_max, res.n_used


def speed_section(dt: float, numbers: dict | None = None) -> list[str]:
    """Real-time factors (simulated s per wall s) of both models: one probe, and a batch of 32 on all cores.

    Medians of 3 runs measured in this process (compiled kernels warmed up first); also kept in ``numbers["speed"]``."""
    rng = np.random.default_rng(0)
    probes = [ProbeSpec(obj=pe.ObjectSpec.from_paper(float(rng.uniform(5, 30)), 36.9),
                        motion=pe.PlateMotion.from_paper(float(f), 3.0, 3.0)) for f in np.linspace(14, 24, 32)]
    lines = ["", "## Speed (A_p 3 deg, 14-24 Hz, objects 5pi-30pi, default windows; medians of 3 runs, rigid_limit: 1)",
             "",
             "| model | dt (s) | one probe, real-time factor | batch of 32, aggregate real-time factor |",
             "|---|---|---|---|"]
    for name, kw in (("pointmass", {}), ("rigid", {"model": "rigid", "dt": dt}),
                     ("rigid_limit", {"model": "rigid_limit"})):
        physics = pe.make_physics("tilelink", **kw)
        physics.run(probes[:2])
        one, batch = [], []
        for _ in range(1 if name == "rigid_limit" else 3):
            t0 = time.perf_counter()
            res = physics.run(probes[:1])
            one.append(res[0].sim_s / (time.perf_counter() - t0))
            t0 = time.perf_counter()
            res = physics.run(probes)
            batch.append(sum(r.sim_s for r in res) / (time.perf_counter() - t0))
        lines.append(f"| {name} | {getattr(physics, 'dt', dt):g} | {np.median(one):.1f} | {np.median(batch):.1f} |")
        if numbers is not None:
            numbers.setdefault("speed", {})[name] = {"one_probe_rtf": float(np.median(one)),
                                                     "batch32_rtf": float(np.median(batch))}
        print(lines[-1], flush=True)
    return lines


def extra_sections(dt: float) -> list[str]:
    """Rigid model: dt convergence at 18/22/25 Hz, sensitivity to the rigid rows' stiffness, 12-deg folds."""
    from plate_env.physics.tilelink import rigid

    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    fs = (18.0, 22.0, 25.0)
    probes = [ProbeSpec(obj=obj, motion=pe.PlateMotion.from_paper(f, 3.0, 3.0), settle_s=0.6, measure_s=1.0)
              for f in fs]
    base = rigid.RigidTileConfig()
    lines = []
    lim = rigid.RIGID_LIMIT_CONFIG
    for name, cfg0, steps in (
            ("rigid", base, [(4e-4, base.iterations), (dt, base.iterations), (dt, 2 * base.iterations),
                             (dt / 2, base.iterations), (dt / 4, base.iterations), (dt / 8, 2 * base.iterations),
                             (dt / 16, 2 * base.iterations)]),
            ("rigid_limit", lim, [(5e-5, lim.iterations), (2.5e-5, lim.iterations), (1.25e-5, lim.iterations),
                                  (6.25e-6, lim.iterations)])):
        runs = {}
        for step, it in steps:
            cfg = replace(cfg0, iterations=it)
            runs[(step, it)] = pe.make_physics("tilelink", model=name, dt=step, rigid_config=cfg).run(probes)
            print(f"{name}: dt {step:g} s, {it} sweeps done", flush=True)
        ref = runs[steps[-1]]
        lines += ["", f"## {name}: omega_B against dt (10pi, 36.9 deg, 3 deg; omega_rigid {cfg0.omega_rigid:g} rad/s; "
                  f"reference dt = {steps[-1][0]:g} s)", "",
                  "| dt (s) | sweeps | " + " | ".join(f"{f:g} Hz" for f in fs) + " | max |difference| |",
                  "|---|---|" + "---|" * len(fs) + "---|"]
        for (step, it), res in runs.items():
            diffs = [100 * (r.omega_b_deg_s - q.omega_b_deg_s) / q.omega_b_deg_s
                     for r, q in zip(res, ref, strict=True)]
            cells = [f"{r.omega_b_deg_s:.1f}{'*' if r.unstable else ''} ({d:+.2f} %)"
                     for r, d in zip(res, diffs, strict=True)]
            lines.append(f"| {step:g} | {it} | " + " | ".join(cells) + f" | {max(abs(d) for d in diffs):.2f} % |")
    lines += ["", "(* = ended unstable before the window closed; omega_B from the part measured.)", "",
              "## Rigid tiles: omega_B against the stiffness of the 'rigid' rows (omega_rigid, rad/s)", "",
              f"dt = {dt / 8:g} s, {2 * lim.iterations} sweeps (and the default dt {dt:g} s, "
              f"{2 * base.iterations} sweeps, where it runs).", "",
              "| omega_rigid | dt (s) | " + " | ".join(f"{f:g} Hz" for f in fs) + " |",
              "|---|---|" + "---|" * len(fs)]
    for w_r in (1000.0, 2500.0, 5000.0, 10000.0, 20000.0, 40000.0, 80000.0):
        for step, it in ((dt, 2 * base.iterations), (dt / 8, 2 * lim.iterations)):
            if step == dt and w_r > 20000.0:
                continue
            cfg = rigid.RigidTileConfig(omega_rigid=w_r, iterations=it)
            res = pe.make_physics("tilelink", model="rigid", dt=step, rigid_config=cfg).run(probes)
            lines.append(f"| {w_r:g} | {step:g} | " + " | ".join(
                f"{r.omega_b_deg_s:.1f}{'*' if r.unstable else ''}" for r in res) + " |")
            print(lines[-1], flush=True)
    lines += ["", "## Rigid model at A_p = 12 deg (B_p 3 mm, settle 0.8 s, measure 1.0 s)", "",
              "| omega_n | f_p | status | t_end (s) | max bend (deg) | E excess / plate work |",
              "|---|---|---|---|---|---|"]
    specs = [ProbeSpec(obj=pe.ObjectSpec.from_paper(wn, 36.9), motion=pe.PlateMotion.from_paper(f, 12.0, 3.0),
                       settle_s=0.8, measure_s=1.0) for wn in (3.0, 5.0, 10.0) for f in (12.0, 16.0)]
    out = rk.run_rigid_arrays(specs, dt=dt)
    rec = out["prm"][0, P_RECEVERY] * dt
    for b, s in enumerate(specs):
        d = out["diag"][b]
        lines.append(f"| {s.obj.omega_n / math.pi:.0f}pi | {s.motion.freq_hz:g} | "
                     f"{Status(int(out['status'][b])).name} | {int(out['nrec'][b]) * rec:.2f} | "
                     f"{math.degrees(d[1]):.0f} | {d[0]:.2e} / {d[2]:.2e} |")
    return lines


def main() -> None:
    """Run the sweeps and write the markdown report."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="coarser sweep and two objects")
    ap.add_argument("--dt", type=float, default=DEFAULT_DT["rigid"], help="rigid model time step, s")
    args = ap.parse_args()
    freqs = np.arange(14.0, 35.0, 2.0 if args.quick else 1.0)
    objects = [(10.0, 36.9), (33.0, 36.9), (10.0, 56.3)]
    if not args.quick:
        objects += [(20.0, 36.9), (50.0, 36.9)]
    models = {"pointmass": pe.make_physics("tilelink"),
              "rigid": pe.make_physics("tilelink", model="rigid", dt=args.dt),
              "rigid_limit": pe.make_physics("tilelink", model="rigid_limit")}
    spec0 = ProbeSpec(obj=pe.ObjectSpec.from_paper(10.0, 36.9), motion=pe.PlateMotion.from_paper(20.0, 3.0, 3.0))
    lines = ["# Point-mass vs rigid-tile tile-link models", "",
             f"A_p = 3 deg, B_p = 3 mm, ramp {spec0.motion.ramp_s:g} s, settle {spec0.settle_s:g} s, measure "
             f"{spec0.measure_s:g} s; dt: " + ", ".join(f"{k} {m.dt:g} s" for k, m in models.items())
             + ". First-hump fit of Eq. (9) by the package's fitter (stable probes up to the first dip). "
             "rigid_limit: the joint rows at 40000 rad/s (their converged rigid limit), 4 sweeps.", "",
             "| omega_n (pi rad/s) | alpha (deg) | model | f0 (Hz) | b (Hz) | omega_max (deg/s) | points | "
             "paper f0/b/max | wall s (batch) | RT aggregate |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    sweeps = []
    numbers: dict = {"command": "python experiments/bench_models.py" + " --quick" * args.quick, "fits": [],
                     "slope_hz_per_pi": {}, "paper_slope_hz_per_pi": round((28.2 - 25.1) / 23, 3)}
    f0s: dict[str, list[tuple[float, float]]] = {name: [] for name in models}
    for wn, alpha in objects:
        obj = pe.ObjectSpec.from_paper(wn, alpha)
        probes = [ProbeSpec(obj=obj, motion=pe.PlateMotion.from_paper(float(f), 3.0, 3.0)) for f in freqs]
        sim_s = sum(p.duration_s for p in probes)
        paper = PAPER.get((wn, alpha))
        ptxt = "/".join(f"{x:g}" for x in paper) if paper else "-"
        per_model = {}
        for name, physics in models.items():
            t0 = time.perf_counter()
            res = physics.run(probes)
            wall = time.perf_counter() - t0
            w = np.array([r.omega_b_deg_s for r in res])
            u = np.array([r.unstable for r in res])
            per_model[name] = (w, u)
            f0, b, wmax, npts = fit(freqs, w, u)
            if alpha == 36.9 and math.isfinite(f0):
                f0s[name].append((wn, f0))
            lines.append(f"| {wn:g} | {alpha:g} | {name} | {f0:.1f} | {b:.1f} | {wmax:.0f} | {npts} | {ptxt} | "
                         f"{wall:.1f} | {sim_s / wall:.1f} |")
            numbers["fits"].append({"omega_n_pi": wn, "alpha_deg": alpha, "model": name, "f0_hz": f0, "b_hz": b,
                                    "omega_max_deg_s": wmax, "points": npts, "paper": paper, "wall_s": wall,
                                    "rt_aggregate": sim_s / wall})
            print(lines[-1], flush=True)
        sweeps.append((wn, alpha, per_model))
    lines += ["", "Slope of f0 against omega_n (alpha 36.9 deg), Hz per (pi rad/s):", ""]
    for name, pts in f0s.items():
        if len(pts) >= 2:
            x, y = np.array(pts).T
            pts_txt = ", ".join(f"{a:g}:{c:.1f}" for a, c in pts)
            lines.append(f"- {name}: {np.polyfit(x, y, 1)[0]:.3f} (points {pts_txt})")
            numbers["slope_hz_per_pi"][name] = float(np.polyfit(x, y, 1)[0])
    lines.append("- paper: (28.2 - 25.1) / 23 = 0.135")
    lines += ["", "## omega_B per probe (deg/s; * = unstable)", ""]
    lines.append("| omega_n | alpha | f_p | " + " | ".join(models) + " |")
    lines.append("|---|---|---|" + "---|" * len(models))
    for wn, alpha, per_model in sweeps:
        for k, f in enumerate(freqs):
            lines.append(f"| {wn:g} | {alpha:g} | {f:g} | " + " | ".join(
                f"{w[k]:.0f}{'*' if u[k] else ''}" for w, u in per_model.values()) + " |")
    lines += speed_section(args.dt, numbers)
    lines += extra_sections(args.dt)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text("\n".join(lines) + "\n")
    RESULTS.with_suffix(".json").write_text(json.dumps(numbers, indent=1) + "\n")
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
