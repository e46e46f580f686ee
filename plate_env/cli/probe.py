"""``plate-env probe``: run one probe and print omega_B."""

from __future__ import annotations

import argparse
import json
import math
from typing import TYPE_CHECKING

from plate_env.cli.options import add_common, number_arg, object_spec, physics_options, probe_spec
from plate_env.core import checks
from plate_env.core.probe import MIN_PROBE_FREQ_HZ
from plate_env.core.setup import (
    FREQ_RANGE_HZ,
)
from plate_env.core.streams import stdout_to_stderr
from plate_env.core.units import format_omega_pi
from plate_env.physics import make_physics

if TYPE_CHECKING:
    from plate_env.cli.options import Subparsers
    from plate_env.physics import Physics


def add_parser(sub: Subparsers) -> None:
    """The ``probe`` command on the CLI's subparsers ``sub``."""
    p = sub.add_parser("probe", help="run one probe and print omega_B")
    add_common(p)
    p.add_argument("--freq", type=number_arg(checks.real, MIN_PROBE_FREQ_HZ, FREQ_RANGE_HZ[1], unit="Hz"),
                   required=True, help="plate frequency f_p, Hz")


def _physics(args: argparse.Namespace) -> Physics:
    return make_physics(args.physics, **physics_options(args))


def run(args: argparse.Namespace) -> int:
    obj = object_spec(args)
    spec = probe_spec(args, obj, args.freq)
    physics = _physics(args)
    try:
        with stdout_to_stderr():  # what the physics prints below Python: stdout is for the result
            result = physics.run([spec])[0]
    finally:
        physics.close()
    if args.json:
        print(json.dumps({"physics": args.physics, "object": obj.name, **result.to_dict()}))
    else:
        state = f"UNSTABLE ({result.reason})" if result.unstable else "stable"
        print(f"{args.physics}: omega_n={format_omega_pi(obj.omega_n)} rad/s alpha={math.degrees(obj.alpha):.1f} deg "
              f"f_p={args.freq:g} Hz A_p={args.amp:g} deg B_p={args.bp:g} mm")
        print(f"omega_B = {result.omega_b_deg_s:.1f} +- {result.stderr_deg_s:.1f} deg/s  [{state}]  "
              f"{result.periods_measured} periods, {result.sim_s:.2f} s simulated in {result.wall_s:.3f} s")
    return 0
