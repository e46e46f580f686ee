"""Where a ``rigid_fast`` step's time goes (issue 26, 4th route: the kernel itself made faster).

Two measurements in one process, CPU time (``time.process_time``: less sensitive to the shared machine's load than
wall time, which ``rigid_fast_validation.py`` reports), the cheese at 20 Hz, 3 deg, 0.5 s:

* **A/B**: ``plate_env.physics.tilelink.rigid_kernels`` of commit ``--ref`` (read with ``git show`` into a
  temporary module) against the worktree's, alternating, median of ``--repeats``; both single-threaded.
* **Stages**: the worktree kernel's step with one stage run twice (the second time on the same state: an extra
  Gauss-Seidel sweep for the passes, a recomputation for the pure stages, a zero step for the explicit ones),
  the extra time per step against the plain step. A stage's cost in its context (caches, branch history), not a
  micro-benchmark; the shares need not sum to 100 %. The warm start cannot run twice without changing the
  dynamics, so the joint setup is timed as a recomputation without it.

Writes ``experiments/results/rigid_fast_profile.{json,md}``.
Usage: ``nice -n 5 python experiments/rigid_fast_profile.py [--ref 690d019] [--repeats 7]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

import plate_env as pe
from plate_env.core.probe import ProbeSpec
from plate_env.physics.tilelink import rigid_kernels as rk
from plate_env.physics.tilelink.kernels import FAST, plate_state
from plate_env.physics.tilelink.params import (
    P_AMP,
    P_BP,
    P_CC,
    P_DT,
    P_FREQ,
    P_G,
    P_KC,
    P_MASS,
    P_MUK,
    P_MUS,
    P_NSTEPS,
    P_RAMP,
    P_VT,
)
from plate_env.physics.tilelink.rigid import RIGID_FAST_CONFIG, joint_order

HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "rigid_fast_profile"
STAGES = ("plate motion (sin, cos)", "tile axes", "gravity + gyroscopic", "joint setup (no warm start)",
          "active corners (spring)", "contact sweep", "joint sweep", "integrate (+ axes)")
DT = 2.5e-5


@numba.njit(fastmath=FAST)
def _steps(prm, rest, links, link_dir, n_steps, twice):
    """``n_steps`` of the rigid_fast step (rigid_kernels.rigid_probe without records), stage ``twice`` (1-8, 0:
    none) run a second time."""
    n, nj = rest.shape[0], links.shape[0]
    inv_m, dt, ixx, izz = 1.0 / prm[P_MASS], prm[P_DT], prm[rk.R_IXX], prm[rk.R_IZZ]
    ixx_inv, dinv = 1.0 / ixx, 1.0 / izz - 1.0 / ixx
    kc, cc, hh = prm[P_KC] * prm[rk.R_CORNERW], prm[P_CC] * prm[rk.R_CORNERW], 0.5 * prm[rk.R_H]
    _, gam, kfac = rk._row_constants(prm, dt)
    x, v, q, w, ax = np.empty((n, 3)), np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, 3)), np.empty((n, 9))
    jra, jrb, jfr = np.empty((nj, 3)), np.empty((nj, 3)), np.empty((nj, 9))
    jkt, jkr = np.empty((nj, 6)), np.empty((nj, 3))
    jb, jc, pacc, pzero = np.empty((nj, 5)), np.zeros((nj, 5)), np.zeros((nj, 5)), np.zeros((nj, 5))
    ctile, cdat, cimp = np.empty(4 * n, dtype=np.int64), np.empty((4 * n, 11)), np.empty((4 * n, 3))
    rk._place_tiles(prm, rest, x, q)
    rk._tile_axes(q, ax)
    bend, work, work_abs = 0.0, 0.0, 0.0
    for step in range(n_steps):
        for rep in range(2 if twice == 1 else 1):
            th, th_dot, xp, xp_dot = plate_state((step + 0.5 * rep) * dt, prm[P_FREQ], prm[P_AMP], prm[P_BP],
                                                 prm[P_RAMP])
            s_th, c_th = math.sin(th), math.cos(th)
        if twice == 2:
            rk._tile_axes(q, ax)
        rk._gravity_and_gyroscopic(v, w, ax, dt, prm[P_G], ixx, izz, ixx_inv, dinv)
        if twice == 3:
            rk._gravity_and_gyroscopic(v, w, ax, 0.0, prm[P_G], ixx, izz, ixx_inv, dinv)
        bend = rk._joint_setup(step % 10 == 0, x, v, w, ax, links, link_dir, hh, inv_m, ixx_inv, dinv, gam, kfac,
                               jra, jrb, jfr, jkt, jkr, jb, jc, pacc, bend)
        if twice == 4:
            bend = rk._joint_setup(False, x, v, w, ax, links, link_dir, hh, inv_m, ixx_inv, dinv, gam, kfac, jra, jrb,
                                   jfr, jkt, jkr, jb, jc, pzero, bend)
        for _ in range(2 if twice == 5 else 1):
            n_act = rk._active_corners(x, ax, hh, s_th, c_th, th_dot, xp_dot, kc, inv_m, ixx_inv, dinv, ctile, cdat,
                                       cimp)
        for it in range(2 if twice == 6 else 1):
            rk._contact_pass(it, n_act, ctile, cdat, cimp, v, w, ax, s_th, c_th, dt, cc, prm[P_MUS], prm[P_MUK],
                             prm[P_VT], inv_m, ixx_inv, dinv)
        for it in range(2 if twice == 7 else 1):
            rk._joint_pass(it, links, jra, jrb, jfr, jkt, jkr, jb, gam, pacc, v, w, ax, inv_m, ixx_inv, dinv)
        work, work_abs = rk._plate_work(n_act, cimp, cdat, work, work_abs)
        rk._integrate(x, v, q, w, ax, dt)
        if twice == 8:
            rk._integrate(x, v, q, w, ax, 0.0)
    return bend + work + v[0, 0]


def _old_kernels(ref: str):
    """rigid_kernels.py of commit ``ref`` as a module of its own (compiled into a temporary numba cache)."""
    src = subprocess.run(["git", "show", f"{ref}:plate_env/physics/tilelink/rigid_kernels.py"], cwd=HERE,
                         capture_output=True, text=True, check=True).stdout
    path = Path(tempfile.mkdtemp()) / f"rigid_kernels_{ref}.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def ab(ref: str, repeats: int, probe: ProbeSpec) -> dict:
    """CPU seconds per step of the ``ref`` kernel and the worktree's on ``probe``, alternating."""
    old = _old_kernels(ref)
    steps = rk.param_vector(probe, DT, 0.05, RIGID_FAST_CONFIG)[P_NSTEPS]  # the probe's steps (settle, measure, ramp)
    times: dict[str, list[float]] = {"ref": [], "now": []}
    for rep in range(repeats + 1):
        for name, mod in (("ref", old), ("now", rk)):
            t0 = time.process_time()
            mod.run_rigid_arrays([probe], dt=DT, config=RIGID_FAST_CONFIG, parallel=False)
            if rep:  # the first round compiles / loads
                times[name].append(time.process_time() - t0)
    ratios = [a / b for a, b in zip(times["ref"], times["now"], strict=True)]
    return {"ref": ref, "us_per_step_ref": 1e6 * statistics.median(times["ref"]) / steps,
            "us_per_step_now": 1e6 * statistics.median(times["now"]) / steps,
            "speedup_median": statistics.median(ratios),
            "speedup_min": min(ratios), "speedup_max": max(ratios)}


def stages(repeats: int, probe: ProbeSpec, n_steps: int = 20000) -> dict:
    """Extra CPU microseconds per step of each stage run twice (``_steps``), min over ``repeats``."""
    prm = rk.param_vector(probe, DT, 0.05, RIGID_FAST_CONFIG)
    geom = rk._params(probe.obj, RIGID_FAST_CONFIG).geom
    order = joint_order(geom)
    args = (prm, geom.rest, geom.links[order], geom.link_dir[order])
    _steps(*args, 10, 0)
    cpu = {k: [] for k in range(len(STAGES) + 1)}
    for _ in range(repeats):
        for k in cpu:
            t0 = time.process_time()
            _steps(*args, n_steps, k)
            cpu[k].append(time.process_time() - t0)
    base = min(cpu[0]) / n_steps
    return {"us_per_step": 1e6 * base, "stages_us": {STAGES[k - 1]: 1e6 * (min(cpu[k]) / n_steps - base)
                                                       for k in range(1, len(STAGES) + 1)}}


def markdown(rep: dict) -> str:
    a, s = rep["ab"], rep["stages"]
    lines = ["# Issue 26, 4th route: the rigid_fast kernel made faster", "",
             f"Written by `python experiments/rigid_fast_profile.py` (CPU time, one process, load {rep['load']:.1f}; "
             "the cheese at 20 Hz, 3 deg, 0.5 s).", "",
             f"A/B against the kernel of {a['ref']}: {a['us_per_step_ref']:.2f} -> {a['us_per_step_now']:.2f} CPU us "
             f"per step, **{a['speedup_median']:.2f}x** (median of the paired ratios; {a['speedup_min']:.2f}-"
             f"{a['speedup_max']:.2f}).", "",
             f"Budget: 10x real time at dt {DT:g} s is {DT / 10 * 1e6:.2f} us per step; 25x aggregate on 2 cores is "
             f"{2 * DT / 25 * 1e6:.2f} us per step and core.", "",
             f"Stages of the step now ({s['us_per_step']:.2f} us per step without records; each stage run twice, "
             "the extra time):", "", "| stage | us per step | share |", "|---|---|---|"]
    for k, us in s["stages_us"].items():
        lines.append(f"| {k} | {us:.2f} | {us / s['us_per_step']:.0%} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", default="690d019", help="commit whose rigid kernel is the A/B reference")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    probe = ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(20.0, 3.0), settle_s=0.2, measure_s=0.3)
    rep = {"ab": ab(args.ref, args.repeats, probe), "stages": stages(max(3, args.repeats // 2), probe),
           "load": os.getloadavg()[0]}
    OUT.with_suffix(".json").write_text(json.dumps(rep, indent=1) + "\n")
    OUT.with_suffix(".md").write_text(markdown(rep))
    print(markdown(rep))


if __name__ == "__main__":
    sys.exit(main())
