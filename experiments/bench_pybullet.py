"""Time vs error of the PyBullet sheet: omega_B error against a converged reference and real-time factor
over mesh resolution (points per layer) and time step; plus a profile of one step.

Run: ``python experiments/bench_pybullet.py`` (a few minutes, one process); ``--rss`` measures memory over
200 scene builds instead. Writes
``experiments/results/pybullet_bench.md`` and ``pybullet_bench.png``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

import plate_env as pe
from plate_env.physics.pybullet_sheet import PyBulletPhysics, SheetConfig
from plate_env.physics.pybullet_sheet.calibrate import calibrated_k
from plate_env.physics.pybullet_sheet.scene import Client, SheetScene
from plate_env.plotting import new_figure, save_figure

OUT = Path(__file__).resolve().parent / "results"
OBJ = pe.ObjectSpec.from_paper(10.0, 36.9)
FREQS = (18.0, 22.0)
REF = (150, 1e-4)
GRID = [(n, dt) for n in (30, 50, 70, 91) for dt in (1e-4, 2e-4, 4e-4, 8e-4)]


def probes() -> list[pe.ProbeSpec]:
    return [pe.ProbeSpec(OBJ, pe.PlateMotion.from_paper(f, 3.0, 3.0), settle_s=0.4, measure_s=0.6) for f in FREQS]


def run(n: int, dt: float) -> tuple[np.ndarray, float, list]:
    phys = PyBulletPhysics(dt=dt, n_layer=n, sequence_len=1)
    cfg = phys.config
    calibrated_k(OBJ, cfg)  # calibration outside the timing
    t0 = time.perf_counter()
    res = phys.run(probes())
    wall = time.perf_counter() - t0
    phys.close()
    sim = sum(r.sim_s for r in res)
    return np.array([r.omega_b_deg_s for r in res]), sim / wall, res


def profile(n: int = 70, dt: float = 4e-4, steps: int = 2000) -> dict[str, float]:
    """Microseconds per call of the parts of one step, sheet resting in contact on a moving plate."""
    client = Client()
    cfg = SheetConfig(n_layer=n, dt=dt)
    sc = SheetScene(client, OBJ, calibrated_k(OBJ, cfg)[0], cfg)
    mot = pe.PlateMotion.from_paper(24.0, 3.0)
    out = {"stepSimulation": 0.0, "resetJointState x2": 0.0, "getMeshData": 0.0}
    for i in range(steps):
        th, thd, x, xd = mot.state(i * dt)
        t0 = time.perf_counter()
        sc.set_plate(th, thd, x, xd)
        t1 = time.perf_counter()
        sc.step()
        t2 = time.perf_counter()
        if i % 10 == 0:
            sc.positions()
        t3 = time.perf_counter()
        out["resetJointState x2"] += t1 - t0
        out["stepSimulation"] += t2 - t1
        out["getMeshData"] += (t3 - t2) * 10
    client.close()
    return {k: 1e6 * v / steps for k, v in out.items()}


def rss_mb() -> float:
    """Resident set size of this process, MB (Linux /proc)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def rss_over_builds(n_builds: int = 200) -> list[tuple[int, float]]:
    """RSS (MB) after 1..n_builds scene builds on one client (each build: resetSimulation + mesh + plate + load)."""
    client = Client()
    cfg = SheetConfig()
    out = []
    for i in range(1, n_builds + 1):
        sc = SheetScene(client, OBJ, 13.6, cfg)
        for _ in range(20):
            sc.step()
        if i in (1, 10, 50, 100, 150, 200) or i == n_builds:
            out.append((i, rss_mb()))
    client.close()
    return out


def main() -> None:
    OUT.mkdir(exist_ok=True)
    if "--rss" in sys.argv:
        rows = rss_over_builds()
        text = "# PyBullet sheet: RSS over repeated scene builds\n\n| builds | RSS (MB) |\n|---|---|\n"
        text += "".join(f"| {i} | {m:.1f} |\n" for i, m in rows)
        (OUT / "pybullet_rss.md").write_text(text)
        print(text)
        return
    ref, ref_rtf, ref_res = run(*REF)
    rows = []
    for n, dt in GRID:
        w, rtf, res = run(n, dt)
        err = np.abs(w / ref - 1) * 100
        unst = sum(r.unstable for r in res)
        rows.append((n, dt, w, err, rtf, unst))
        print(n, dt, w.round(1), err.round(1), round(rtf, 3), unst, flush=True)
    prof = profile()
    lines = ["# PyBullet sheet: omega_B error vs converged reference, and real-time factor", "",
             f"Object 10pi, alpha 36.9 deg, A_p 3 deg, B_p 3 mm, f_p {FREQS} Hz, settle 0.4 s + measure 0.6 s.",
             f"Reference: {REF[0]} points/layer ({2 * REF[0]} nodes), dt {REF[1]:g} s: omega_B = "
             f"{ref.round(1).tolist()} deg/s (unstable: {[r.reason for r in ref_res]}), rtf {ref_rtf:.3f}.", "",
             "| points/layer | nodes | dt (s) | omega_B (deg/s) | error vs ref (%) | real-time factor | unstable |",
             "|---|---|---|---|---|---|---|"]
    for n, dt, w, err, rtf, unst in rows:
        lines.append(f"| {n} | {2 * n} | {dt:g} | {', '.join(f'{v:.1f}' for v in w)} | "
                     f"{', '.join(f'{v:.1f}' for v in err)} | {rtf:.3f} | {unst} |")
    lines += ["", "Step profile (70 points/layer, dt 4e-4 s, in contact, microseconds per step):", ""]
    lines += [f"- {k}: {v:.1f}" for k, v in prof.items()]
    (OUT / "pybullet_bench.md").write_text("\n".join(lines) + "\n")
    fig, ax = new_figure(figsize=(5, 3.5))
    for n in sorted({r[0] for r in rows}):
        sel = [r for r in rows if r[0] == n]
        ax.plot([r[4] for r in sel], [r[3].max() for r in sel], "o-", label=f"{2 * n} nodes")
        for r in sel:
            ax.annotate(f"{r[1]:g}", (r[4], r[3].max()), fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("real-time factor (sim s / wall s)")
    ax.set_ylabel("max |omega_B error| vs ref (%)")
    ax.legend(fontsize=8)
    save_figure(fig, OUT / "pybullet_bench.png", dpi=90)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
