"""Structural numbers for the issue-26 routes that were measured but not built as kernels.

* Exact velocity-level solve of the joint system with its fixed sparsity: the 5 rows x 88 joints system
  ``A = J M^-1 J^T + Gamma`` (rest geometry, the rows as backward-Euler spring-dampers at dt), reordered by reverse
  Cuthill-McKee; the nonzeros of its Cholesky factor give the flops of one forward/backward solve, timed here in
  numba, with a whole `rigid_fast` step timed in the same run, split into its fixed part (frames, contact
  detection, warm start, records) and one more sweep (contacts + joints).
* Reduced coordinates: the null space of the held rows' rest Jacobian (rows 1, 2, 4 of each joint): its dimension
  in plane and out of plane, and how dense an orthonormal basis is (a dense basis maps 312 tile velocities to the
  reduced ones at 2 x 312 x r flops per use); where the nearly-constant Jacobian stops holding is read from the
  largest bending angle the `rigid_fast` model reaches at 3 and 12 deg (the held rows' Jacobian turns with it).

Usage: ``python experiments/rigid_fast_structure.py`` (prints JSON); ``rigid_fast_validation.py`` embeds it.
"""

from __future__ import annotations

import json
import math
import time

import numba
import numpy as np

import plate_env as pe
from plate_env.core.probe import ProbeSpec
from plate_env.physics.tilelink import rigid
from plate_env.physics.tilelink import rigid_kernels as rk
from plate_env.physics.tilelink.params import DEFAULT_DT, P_NSTEPS


@numba.njit(cache=True)
def _band_solve(lb, b, bw):
    """Solve L L^T x = b with L lower banded (lb[i, k] = L[i, i - k], k <= bw), in place."""
    n = b.shape[0]
    for i in range(n):
        s = b[i]
        for k in range(1, min(bw, i) + 1):
            s -= lb[i, k] * b[i - k]
        b[i] = s / lb[i, 0]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(1, min(bw, n - 1 - i) + 1):
            s -= lb[i + k, k] * b[i + k]
        b[i] = s / lb[i, 0]


def _step_us(sweeps: int) -> float:
    """Wall microseconds of one rigid_fast step with ``sweeps`` sweeps (median of 3, one probe, 10pi at 20 Hz)."""
    from dataclasses import replace

    spec = ProbeSpec(obj=pe.ObjectSpec.from_paper(10.0, 36.9), motion=pe.PlateMotion.from_paper(20.0, 3.0, 3.0),
                     settle_s=0.1, measure_s=0.3)
    cfg = replace(rigid.RIGID_FAST_CONFIG, iterations=sweeps)
    rk.run_rigid_arrays([spec], dt=DEFAULT_DT["rigid_fast"], config=cfg, parallel=False)
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        run = rk.run_rigid_arrays([spec], dt=DEFAULT_DT["rigid_fast"], config=cfg, parallel=False)
        times.append((time.perf_counter() - t0) / run["prm"][0, P_NSTEPS])
    return 1e6 * float(np.median(times))


def exact_solve(dt: float = 1e-4) -> dict:
    """Size, fill and solve time of the joint system's banded Cholesky factor at the rest geometry."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    p = rigid.build_params(obj, rigid.RIGID_FAST_CONFIG)
    jac = rigid.joint_jacobian(p.geom)
    minv = 1.0 / np.diag(rigid.mass_matrix(p.geom, p.tile_mass))
    gam = np.tile(1.0 / (dt * (dt * p.row_k + p.row_c)), len(p.geom.links))
    a = (jac * minv) @ jac.T + np.diag(gam)
    perm = reverse_cuthill_mckee(csr_matrix(np.abs(a) > 0), symmetric_mode=True)
    ap_ = a[np.ix_(perm, perm)]
    ll = np.linalg.cholesky(ap_)
    n = len(ap_)
    rows, cols = np.nonzero(np.abs(ll) > 0)
    bw = int(np.max(rows - cols))
    lb = np.zeros((n, bw + 1))
    for k in range(bw + 1):
        lb[k:, k] = np.diagonal(ll, -k)
    b = np.ones(n)
    _band_solve(lb, b.copy(), bw)
    t0 = time.perf_counter()
    reps = 2000
    for _ in range(reps):
        _band_solve(lb, b.copy(), bw)
    per = (time.perf_counter() - t0) / reps
    step_us = {sweeps: _step_us(sweeps) for sweeps in (1, 2)}
    return {"rows": n, "bandwidth_rcm": bw, "rigid_fast_step_us_same_run": step_us[1],
            "one_more_sweep_us": step_us[2] - step_us[1], "fixed_part_of_a_step_us": 2 * step_us[1] - step_us[2],
            "factor_band_entries": int(n * (bw + 1)),
            "factor_nonzeros": int(np.count_nonzero(np.abs(ll) > 1e-300)),
            "flops_per_solve": int(4 * n * (bw + 1)), "solve_us": 1e6 * per, "dt_s": dt}


def null_space() -> dict:
    """Dimension and density of the held rows' rest null space, in plane and out of plane."""
    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    p = rigid.build_params(obj, rigid.RIGID_FAST_CONFIG)
    jac = rigid.joint_jacobian(p.geom)
    nj = len(p.geom.links)
    held = jac[[5 * j + r for j in range(nj) for r in (1, 2, 4)]]
    out = {}
    oop = rigid.out_of_plane_dofs(p.geom)
    for name, mask in (("in_plane", ~oop), ("out_of_plane", oop)):
        sub = held[:, mask]
        sub = sub[np.any(sub != 0, axis=1)]
        s = np.linalg.svd(sub, compute_uv=False)
        rank = int(np.sum(s > 1e-9 * s[0]))
        _, _, vt = np.linalg.svd(sub)
        basis = vt[rank:].T
        density = float(np.mean(np.abs(basis) > 1e-8 * np.abs(basis).max()))
        out[name] = {"dofs": int(mask.sum()), "rows": int(len(sub)), "rank": rank,
                     "null_dim": int(mask.sum()) - rank, "basis_density": density}
    r = out["in_plane"]["null_dim"] + out["out_of_plane"]["null_dim"]
    out["dense_map_flops"] = 2 * int(jac.shape[1]) * r
    return out


def bend_angles() -> dict:
    """Largest joint bending angle (deg) the rigid_fast model reaches: where a frozen Jacobian stops holding."""
    cases = [(10.0, 22.0, 3.0), (10.0, 26.0, 3.0), (33.0, 28.0, 3.0), (10.0, 13.0, 12.0)]
    specs = [ProbeSpec(obj=pe.ObjectSpec.from_paper(wn, 36.9), motion=pe.PlateMotion.from_paper(f, a, 3.0))
             for wn, f, a in cases]
    out = rk.run_rigid_arrays(specs, dt=DEFAULT_DT["rigid_fast"], config=rigid.RIGID_FAST_CONFIG)
    return {f"{wn:g}pi_{f:g}Hz_{a:g}deg": round(math.degrees(out["diag"][b, 1]), 2)
            for b, (wn, f, a) in enumerate(cases)}


def measure() -> dict:
    return {"exact_solve": exact_solve(), "null_space": null_space(), "max_bend_deg": bend_angles()}


if __name__ == "__main__":
    print(json.dumps(measure(), indent=1))
