"""omega_B of three rigid-tile probes (10 pi rad/s, 36.9 deg, A_p 3 deg, 18/22/25 Hz, dt 2e-4 s: bench_models.py's
dt table), printed with every digit, for the tree on PYTHONPATH: which commit moved the rigid models' numbers.

    python experiments/rigid_probe_values.py LABEL

Used to bisect why experiments/bench_models.py's rigid and rigid_limit omega_B moved by 1-2 % per probe between its
runs of 2026-11-24 (5c1d708) and 2026-12-02 (8d7ec1f): in a worktree,
``git bisect start 8d7ec1f 5c1d708 && git bisect run SCRIPT``, SCRIPT running this file with
``PYTHONPATH=<a directory linking plate_env to the worktree's>`` and exiting 0 when the 22 Hz value is 5c1d708's.
It names ae5c174 (rigid_probe split into inlined stages, fastmath): docs/conventions.md, Determinism.
"""

from __future__ import annotations

import sys

import plate_env as pe
from plate_env.physics.tilelink import rigid


def main() -> None:
    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    probes = [pe.ProbeSpec(obj=obj, motion=pe.PlateMotion.from_paper(f, 3.0, 3.0), settle_s=0.6, measure_s=1.0)
              for f in (18.0, 22.0, 25.0)]
    res = pe.make_physics("tilelink", model="rigid", dt=2e-4, rigid_config=rigid.RigidTileConfig()).run(probes)
    print(sys.argv[1] if len(sys.argv) > 1 else "", [repr(r.omega_b_deg_s) for r in res])


if __name__ == "__main__":
    main()
