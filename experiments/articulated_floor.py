"""Issue 34: the articulated-disc route's floor, counted on the project's own joint rows and timed, before building it.

The articulated disc would write the tiles in relative joint coordinates over a spanning tree of the 88 joints and
close the remaining loops by constraints. Two numbers decide whether it can be fast:

1. **Counts** (from :func:`plate_env.physics.tilelink.rigid.joint_jacobian`, the kernel's linearised rows): a
   joint's held rows are its four rows other than bending (compression, edge and normal translation, rotation about
   the normal), which leave each tree joint two coordinates. The rank of all held rows says how many are redundant:
   redundant rows are the ones whose strain carries the geometric stiffening of non-developable bends (the modal
   route's quartic term). Kept rigid they lock those bends, which is not the rigid limit's physics: its held rows
   are springs at ``omega_rigid`` = 40,000 rad/s. Kept compliant they are as stiff as in maximal coordinates, and so
   need an implicit solve every step.
2. **Time** of that implicit solve at the counted sizes, with nothing else in the step (no contact, no tree
   dynamics beyond factoring its mass matrix): the mass matrix's Cholesky factor, the Delassus operator
   ``J M^-1 J^T`` of the closure rows plus their compliance, and its factor. One thread, numpy/LAPACK.

Prints the counts and the per-step time as x real time at dt 4e-4 and 2e-4 s. Usage:
``OPENBLAS_NUM_THREADS=1 python experiments/articulated_floor.py [--steps 2000]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.linalg

import plate_env as pe
from plate_env.physics.tilelink.geometry import disc_geometry
from plate_env.physics.tilelink.rigid import DOF_PER_TILE, joint_jacobian

ROWS_PER_JOINT = 5
BENDING_ROW = 3


def counts(omega_n_pi: float = 10.0) -> dict[str, int]:
    """Tiles, joints, tree coordinates and closure rows of the articulated disc, and the held rows' rank."""
    geom = disc_geometry(pe.ObjectSpec.from_paper(omega_n_pi, 36.9).diameter)
    jac = joint_jacobian(geom)
    held = np.ones(jac.shape[0], dtype=bool)
    held[BENDING_ROW::ROWS_PER_JOINT] = False
    sv = np.linalg.svd(jac[held], compute_uv=False)
    rank = int(np.sum(sv > 1e-9 * sv[0]))
    n_tiles, n_joints = geom.n_nodes, len(geom.links)
    held_per_joint = ROWS_PER_JOINT - 1
    tree_joints = n_tiles - 1
    return {"tiles": n_tiles, "joints": n_joints, "held_rows": int(held.sum()), "held_rank": rank,
            "redundant_held_rows": int(held.sum()) - rank,
            "first_order_mechanisms_incl_rigid": DOF_PER_TILE * n_tiles - rank,
            "tree_coordinates": 6 + tree_joints * (DOF_PER_TILE - held_per_joint),
            "closure_rows": (n_joints - tree_joints) * held_per_joint}


def solve_time_us(n_coords: int, n_rows: int, steps: int, rng: np.random.Generator) -> float:
    """Mean time (us) of one step's implicit closure solve at these sizes (random SPD data)."""
    a = rng.standard_normal((n_coords, n_coords))
    mass = a @ a.T + n_coords * np.eye(n_coords)
    jac = rng.standard_normal((n_rows, n_coords))
    compliance = 1e-3 * np.eye(n_rows)
    rhs = np.ones(n_rows)

    def step() -> np.ndarray:
        lower = np.linalg.cholesky(mass)
        x = scipy.linalg.solve_triangular(lower, jac.T, lower=True)
        factor = scipy.linalg.cho_factor(x.T @ x + compliance, lower=True)
        return scipy.linalg.cho_solve(factor, rhs)

    for _ in range(50):
        step()
    t0 = time.perf_counter()
    for _ in range(steps):
        step()
    return (time.perf_counter() - t0) / steps * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=2000)
    args = ap.parse_args()
    c = counts()
    print(", ".join(f"{k} {v}" for k, v in c.items()))
    us = solve_time_us(c["tree_coordinates"], c["closure_rows"], args.steps, np.random.default_rng(0))
    print(f"implicit closure solve alone: {us:.0f} us a step -> x real time {400 / us:.2f} at dt 4e-4 s, "
          f"{200 / us:.2f} at dt 2e-4 s (one thread; contact and tree dynamics not included)")


if __name__ == "__main__":
    main()
