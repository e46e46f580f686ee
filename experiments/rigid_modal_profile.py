"""Issue 34: a marginal-cost stage profile of ``rigid_modal`` on the speed harness's one probe (cheese 20 Hz, 3 deg).

Each route drops or changes one stage of the default (71 dynamic modes at 10pi-class cut-off 200 Hz, second-order
terms in 10 modes, foreshortening, one contact sweep, dt 2e-4 s); the difference in cost is that stage's share.
Speed is simulated seconds per CPU second of this process (``time.process_time``, ``common.rtf``: median of
``--repeats`` timed runs after a warm-up), the point mass measured beside it: the machine is shared, wall time is not
the kernel's cost. Speed only: accuracy of these routes is in ``rigid_modal_validation.py``.

Usage: ``nice -n 10 python experiments/rigid_modal_profile.py [--repeats 2]`` (prints one JSON line a route).
"""

from __future__ import annotations

import argparse
import json
import os
import time

from common import rtf, speed_probes

import plate_env as pe
from plate_env.physics.tilelink.rigid_modal import ModalDiscConfig
from plate_env.physics.tilelink.rigid_modal_kernels import RigidModalPhysics

#: Routes: (dt s, reduction, contact sweeps a step).
ROUTES = {
    "default (K71, nl10, foreshortening, 1 sweep, dt 2e-4)": (2e-4, ModalDiscConfig(), 1),
    "no second-order terms (nl0)": (2e-4, ModalDiscConfig(n_nonlinear=0), 1),
    "no foreshortening": (2e-4, ModalDiscConfig(foreshortening=False), 1),
    "at most 40 modes": (2e-4, ModalDiscConfig(max_modes=40), 1),
    "at most 20 modes": (2e-4, ModalDiscConfig(max_modes=20), 1),
    "at most 10 modes": (2e-4, ModalDiscConfig(max_modes=10), 1),
    "2 contact sweeps": (2e-4, ModalDiscConfig(), 2),
    "dt 4e-4": (4e-4, ModalDiscConfig(), 1),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    one, _ = speed_probes()
    pm, _ = rtf(pe.make_physics("tilelink"), one, args.repeats, clock=time.process_time)
    print(json.dumps({"route": "point mass", "cpu_rtf": round(pm, 2), "load_avg_1min": os.getloadavg()[0]}))
    for name, (dt, cfg, sweeps) in ROUTES.items():
        r, bad = rtf(RigidModalPhysics(dt, cfg, sweeps), one, args.repeats, clock=time.process_time)
        print(json.dumps({"route": name, "cpu_rtf": round(r, 2), "unstable": bad,
                          "load_avg_1min": os.getloadavg()[0]}), flush=True)


if __name__ == "__main__":
    main()
