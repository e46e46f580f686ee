"""Stability map of the tile-link physics: where probes fail, why, and whether a NaN ever leaks out.

    python experiments/stress.py [--quick] [--pybullet] [--model pointmass]

1. A grid dt x omega_n (1.4pi..40pi rad/s) x A_p (1..24 deg) x f_p (5..45 Hz) x alpha, B_p = 3 mm, windows
   0.3 s settle + 0.5 s measure, centred disc: the share of probes stable and unstable by reason (overturned,
   slipped, non_finite, runaway_energy, left_plate, folded), per dt and per omega_n.
2. The largest stable dt per stiffness, two ways: (a) no numerical blow-up (non_finite / runaway_energy) at this
   dt or any smaller one; (b) stability verdicts agree with the finest dt on >= 90 % of the probes.
3. Energy drift on a still plate (A_p = B_p = 0) over 60 simulated seconds: the disc's rigid-body kinetic energy
   (translation of its centre and yaw, from the recorded trace; I = m R^2 / 2) and its centre/yaw drift.
4. NaN leak check: every number of every result, and the observations and rewards of PlateRotation-v0 episodes on
   the live physics with random and extreme actions (also at a time step that blows up).

``--quick`` (CI, ~1 minute): a 3-dt, 2-stiffness corner grid, 10 s still plate, one short env episode per setting.
Writes experiments/results/stress_<tag>.md and stress_<tag>.png (tag gets ``_quick`` in quick mode).
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from collections import Counter
from pathlib import Path

import numpy as np

import plate_env as pe
from plate_env.core.probe import NON_FINITE, REASONS, RUNAWAY, ProbeResult
from plate_env.env.rotation import PlateRotationEnv
from plate_env.plotting import new_figure, save_figure

SCRIPT = "experiments/stress.py"
BLOWUPS = (NON_FINITE, RUNAWAY)
FULL = {"dt": (1e-4, 2e-4, 3e-4, 4e-4, 6e-4, 8e-4, 1e-3, 1.5e-3), "omega_pi": (1.4, 3.5, 10.0, 23.0, 40.0),
        "amp_deg": (1.0, 3.0, 12.0, 24.0), "f_hz": (5.0, 15.0, 25.0, 35.0, 45.0), "alpha_deg": (30.0, 56.3)}
QUICK = {"dt": (2e-4, 6e-4, 1.5e-3), "omega_pi": (1.4, 10.0, 40.0), "amp_deg": (1.0, 24.0), "f_hz": (5.0, 45.0),
         "alpha_deg": (36.9,)}


def finite_result(r: ProbeResult) -> bool:
    """True when every number of a result (and of its trace, if any) is finite."""
    nums = [r.omega_b_deg_s, r.stderr_deg_s, r.sim_s, r.wall_s, float(r.periods_measured)]
    ok = all(math.isfinite(x) for x in nums)
    if r.trace is not None:
        ok = ok and all(np.all(np.isfinite(a)) for a in (r.trace.t, r.trace.yaw, r.trace.centre_u, r.trace.centre_v))
    return ok


def grid(physics_model: str, g: dict) -> dict[float, list[ProbeResult]]:
    """Run the stability grid; results per dt (one batched call per dt)."""
    out = {}
    for dt in g["dt"]:
        physics = pe.make_physics("tilelink", model=physics_model, dt=dt)
        specs = [pe.ProbeSpec(pe.ObjectSpec.from_paper(w, al), pe.PlateMotion.from_paper(f, a), settle_s=0.3,
                              measure_s=0.5)
                 for w, a, f, al in itertools.product(g["omega_pi"], g["amp_deg"], g["f_hz"], g["alpha_deg"])]
        t0 = time.perf_counter()
        out[dt] = physics.run(specs)
        print(f"dt {dt:g} s: {len(specs)} probes in {time.perf_counter() - t0:.1f} s")
    return out


def still_plate(physics_model: str, omegas_pi, seconds: float, dt: float) -> list[dict]:
    """Energy and drift of the disc on a plate that does not move (A_p = B_p = 0), per stiffness."""
    physics = pe.make_physics("tilelink", model=physics_model, dt=dt)
    still = pe.PlateMotion(freq_hz=20.0, amp_rad=0.0, b_p=0.0)
    specs = [pe.ProbeSpec(pe.ObjectSpec.from_paper(w, 36.9), still, settle_s=0.0, measure_s=seconds,
                          record_trace=True, **place) for w in omegas_pi
             for place in ({}, {"initial_yaw": 0.3, "initial_offset": (5e-4, -3e-4)})]
    rows = []
    for spec, r in zip(specs, physics.run(specs), strict=True):
        tr = r.trace
        o = spec.obj
        dtr = np.diff(tr.t)
        vu, vv, wz = np.diff(tr.centre_u) / dtr, np.diff(tr.centre_v) / dtr, np.diff(tr.yaw) / dtr
        ke = 0.5 * o.mass * (vu ** 2 + vv ** 2) + 0.5 * (0.5 * o.mass * o.radius ** 2) * wz ** 2  # J
        t_mid = tr.t[1:]
        first = ke[(t_mid > 0.2) & (t_mid <= 1.2)]  # the first simulated second after the (empty) ramp
        last = ke[t_mid > t_mid[-1] - 1.0]
        rows.append({"omega_pi": o.omega_n / math.pi, "placed": "centred" if spec.initial_yaw == 0 else "off-centre",
                     "unstable": r.reason or "stable", "finite": finite_result(r),
                     "ke_first_uJ": 1e6 * float(first.mean()) if first.size else math.nan,
                     "ke_last_uJ": 1e6 * float(last.mean()), "ke_max_uJ": 1e6 * float(ke[t_mid > 0.2].max()),
                     "centre_drift_um": 1e6 * math.hypot(tr.centre_u[-1] - tr.centre_u[0],
                                                         tr.centre_v[-1] - tr.centre_v[0]),
                     "yaw_drift_deg": math.degrees(tr.yaw[-1] - tr.yaw[0]), "sim_s": r.sim_s})
    return rows


def env_nan_check(dts, episodes: int, max_probes: int, seed: int) -> list[str]:
    """PlateRotation-v0 on live tile-link physics with random and extreme actions: any non-finite obs/reward?"""
    rng = np.random.default_rng(seed)
    lines = []
    extremes = [np.array(x, dtype=np.float32) for x in
                ([1, 1, 1, -1], [-1, -1, -1, -1], [1, -1, -1, -1], [-1, 1, 1, -1])]
    for dt in dts:
        env = PlateRotationEnv(physics="tilelink", physics_options={"dt": dt}, max_probes=max_probes,
                               omega_n_range_pi=(1.4, 40.0), method="lorentz")
        bad = steps = unstable = 0
        for ep in range(episodes):
            obs, _ = env.reset(seed=int(rng.integers(2 ** 31)))
            bad += int(not np.all(np.isfinite(obs)))
            done = False
            k = 0
            while not done:
                action = extremes[k % len(extremes)] if ep % 2 == 0 else rng.uniform(-1, 1, 4).astype(np.float32)
                action[3] = -1.0
                obs, reward, term, trunc, info = env.step(action)
                steps += 1
                k += 1
                unstable += int(bool(info.get("last_probe", {}).get("unstable")))
                bad += int(not (np.all(np.isfinite(obs)) and math.isfinite(reward)))
                done = term or trunc
        env.close()
        lines.append(f"| {dt:g} | {episodes} | {steps} | {unstable} | {bad} |")
    return lines


def largest_stable_dt(res: dict[float, list[ProbeResult]], omega_pi: float) -> tuple[float | None, float | None]:
    """(a) largest dt with no blow-up at it or any finer dt; (b) largest dt whose verdicts agree >= 90 % with the
    finest dt, for the probes of one stiffness (and every finer dt agrees too)."""
    dts = sorted(res)
    ref = [r.unstable for r in res[dts[0]] if math.isclose(r.spec.obj.omega_n / math.pi, omega_pi)]
    a = b = None
    a_ok = b_ok = True
    for dt in dts:
        rs = [r for r in res[dt] if math.isclose(r.spec.obj.omega_n / math.pi, omega_pi)]
        a_ok = a_ok and not any(r.reason in BLOWUPS for r in rs)
        agree = np.mean([r.unstable == u for r, u in zip(rs, ref, strict=True)])
        b_ok = b_ok and agree >= 0.9
        a = dt if a_ok else a
        b = dt if b_ok else b
    return a, b


def pybullet_tiny() -> list[str]:
    """Four probes on a tiny PyBullet sheet (30 points/layer): a sane and a coarse dt, 3 and 24 deg."""
    lines = ["", "## PyBullet (tiny sheet, 30 points/layer, 10pi, 25 Hz, 0.2 s + 0.3 s windows)", "",
             "| dt [s] | A_p [deg] | result | finite |", "|---|---|---|---|"]
    for dt in (8e-4, 4e-3):
        physics = pe.make_physics("pybullet", n_layer=30, dt=dt)
        specs = [pe.ProbeSpec(pe.ObjectSpec.from_paper(10.0, 36.9), pe.PlateMotion.from_paper(25.0, a),
                              settle_s=0.2, measure_s=0.3) for a in (3.0, 24.0)]
        for s, r in zip(specs, physics.run(specs), strict=True):
            lines.append(f"| {dt:g} | {s.motion.a_p_deg:g} | {r.reason or f'{r.omega_b_deg_s:.0f} deg/s'} | "
                         f"{finite_result(r)} |")
        physics.close()
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="CI mode: a corner grid, about a minute")
    ap.add_argument("--pybullet", action="store_true", help="also four probes on a tiny PyBullet sheet")
    ap.add_argument("--model", default="pointmass")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out-dir", default="experiments/results")
    args = ap.parse_args()
    t_start = time.perf_counter()
    g = QUICK if args.quick else FULL
    tag = f"tilelink_{args.model}" + ("_quick" if args.quick else "")
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    res = grid(args.model, g)
    allres = [r for rs in res.values() for r in rs]
    n_nan = sum(not finite_result(r) for r in allres)
    md = [f"# Stress map: tilelink/{args.model}" + (" (quick)" if args.quick else ""), "",
          f"Regenerate: `python {SCRIPT}" + (" --quick" if args.quick else "") + "`. Grid: dt "
          f"{', '.join(f'{d:g}' for d in g['dt'])} s x omega_n {', '.join(f'{w:g}' for w in g['omega_pi'])} pi rad/s x "
          f"A_p {', '.join(f'{a:g}' for a in g['amp_deg'])} deg x f_p {', '.join(f'{f:g}' for f in g['f_hz'])} Hz x "
          f"alpha {', '.join(f'{a:g}' for a in g['alpha_deg'])} deg; B_p 3 mm, 0.3 s + 0.5 s windows, centred disc. "
          f"{len(allres)} probes, results with a non-finite number: **{n_nan}**.", "",
          "## Outcome shares per dt", "",
          "| dt [s] | stable | " + " | ".join(REASONS) + " |", "|---|---|" + "---|" * len(REASONS)]
    for dt, rs in res.items():
        c = Counter(r.reason or "stable" for r in rs)
        md.append(f"| {dt:g} | {100 * c['stable'] / len(rs):.0f} % | "
                  + " | ".join(f"{100 * c[k] / len(rs):.0f} %" for k in REASONS) + " |")
    md += ["", "## Outcome shares per A_p (all dt)", "", "| A_p [deg] | stable | " + " | ".join(REASONS) + " |",
           "|---|---|" + "---|" * len(REASONS)]
    for a in g["amp_deg"]:
        rs = [r for r in allres if math.isclose(r.spec.motion.a_p_deg, a)]
        c = Counter(r.reason or "stable" for r in rs)
        md.append(f"| {a:g} | {100 * c['stable'] / len(rs):.0f} % | "
                  + " | ".join(f"{100 * c[k] / len(rs):.0f} %" for k in REASONS) + " |")
    md += ["", "## Largest stable dt per stiffness", "",
           "(a) no non_finite/runaway_energy probe at this dt or any finer one; (b) stable/unstable verdicts agree "
           f"with dt = {min(g['dt']):g} s on >= 90 % of this stiffness's probes (and at every finer dt).", "",
           "| omega_n [pi rad/s] | (a) no blow-up [s] | (b) verdicts agree [s] | unstable share at finest dt |",
           "|---|---|---|---|"]
    for w in g["omega_pi"]:
        a, b = largest_stable_dt(res, w)
        fin = [r for r in res[min(g["dt"])] if math.isclose(r.spec.obj.omega_n / math.pi, w)]
        md.append(f"| {w:g} | {a if a is not None else '< ' + format(min(g['dt']), 'g')} | "
                  f"{b if b is not None else '-'} | {100 * np.mean([r.unstable for r in fin]):.0f} % |")
    # plot: unstable share dt x omega_n, blow-up share, reasons per dt
    fig, axes = new_figure(1, 3, figsize=(12, 3.4))
    for ax, pick, title in ((axes[0], lambda r: r.unstable, "unstable share"),
                            (axes[1], lambda r: r.reason in BLOWUPS, "blow-up share (non_finite/runaway)")):
        m = np.array([[np.mean([pick(r) for r in res[dt] if math.isclose(r.spec.obj.omega_n / math.pi, w)])
                       for dt in g["dt"]] for w in g["omega_pi"]])
        im = ax.imshow(m, origin="lower", aspect="auto", vmin=0, vmax=1, cmap="magma_r")
        ax.set_xticks(range(len(g["dt"])), [f"{d * 1e3:g}" for d in g["dt"]], fontsize=7)
        ax.set_yticks(range(len(g["omega_pi"])), [f"{w:g}" for w in g["omega_pi"]], fontsize=7)
        ax.set_xlabel("dt [ms]")
        ax.set_ylabel("omega_n [pi rad/s]")
        ax.set_title(title, fontsize=8)
        fig.colorbar(im, ax=ax)
    bottom = np.zeros(len(g["dt"]))
    for k in ("stable", *REASONS):
        share = np.array([np.mean([(r.reason or "stable") == k for r in res[dt]]) for dt in g["dt"]])
        axes[2].bar(range(len(g["dt"])), share, bottom=bottom, label=k)
        bottom += share
    axes[2].set_xticks(range(len(g["dt"])), [f"{d * 1e3:g}" for d in g["dt"]], fontsize=7)
    axes[2].set_xlabel("dt [ms]")
    axes[2].set_title("outcomes per dt", fontsize=8)
    axes[2].legend(fontsize=6, loc="upper left")
    fig.suptitle(f"tilelink/{args.model} stress map - {SCRIPT}" + (" --quick" if args.quick else ""), fontsize=8)
    save_figure(fig, out_dir / f"stress_{tag}.png", dpi=85)
    md += ["", f"Plot: `stress_{tag}.png`.", ""]
    # still plate
    seconds = 10.0 if args.quick else 60.0
    still_omegas = (1.4, 40.0) if args.quick else (1.4, 3.5, 10.0, 23.0, 40.0)
    md += [f"## Energy drift on a still plate ({seconds:g} simulated s, dt 2e-4 s, A_p = B_p = 0)", "",
           "Rigid-body kinetic energy of the disc (centre translation + yaw, from the 1 ms trace), mean over the "
           "first and the last simulated second, and its maximum; drift of the centre and the yaw end to end.", "",
           "The trace holds the in-plane rigid motion only (no node states): vertical vibration is not seen. "
           "Off-centre: placed 0.58 mm off the centre and turned 0.3 rad.", "",
           "| omega_n [pi rad/s] | placement | outcome | KE first s [uJ] | KE last s [uJ] | KE max [uJ] | "
           "centre drift [um] | yaw drift [deg] | finite |", "|---|---|---|---|---|---|---|---|---|"]
    for row in still_plate(args.model, still_omegas, seconds, 2e-4):
        md.append(f"| {row['omega_pi']:g} | {row['placed']} | {row['unstable']} "
                  f"| {row['ke_first_uJ']:.3g} | {row['ke_last_uJ']:.3g} | "
                  f"{row['ke_max_uJ']:.3g} | {row['centre_drift_um']:.3g} | {row['yaw_drift_deg']:.3g} | "
                  f"{row['finite']} |")
    # env NaN check
    env_dts = (2e-4, 1.5e-3)
    md += ["", "## NaN leak check in PlateRotation-v0 (live tile-link, lorentz method, omega_n 1.4-40pi)", "",
           "Even episodes use extreme actions (band edges, both amplitudes, shortest/longest windows), odd ones "
           "seeded random actions.", "",
           "| dt [s] | episodes | steps | unstable probes | non-finite obs or reward |", "|---|---|---|---|---|"]
    md += env_nan_check(env_dts, 2 if args.quick else 6, 3 if args.quick else 8, args.seed)
    if args.pybullet:
        md += pybullet_tiny()
    md += ["", f"Total wall time of this run: {time.perf_counter() - t_start:.0f} s."]
    (out_dir / f"stress_{tag}.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    if n_nan:
        raise SystemExit(f"{n_nan} results carried a non-finite number")


if __name__ == "__main__":
    main()
