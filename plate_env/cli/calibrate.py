"""``plate-env calibrate``: learn a lab calibration from reference discs of known omega_n."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from plate_env.cli.options import MAX_FIT_ROWS, CliError, add_known_inputs, known_inputs, output_path

if TYPE_CHECKING:
    from plate_env.cli.options import Subparsers


def add_parser(sub: Subparsers) -> None:
    c = sub.add_parser("calibrate", help="learn a lab calibration from reference discs of known omega_n")
    c.add_argument("refs", nargs="+", help="the reference discs: SWEEP.csv=OMEGA (one disc's sweep as `sweep --csv` "
                   "writes it, its known omega_n in rad/s or e.g. 10pi; named after the file) or REFS.csv (several "
                   "discs: the fit columns plus object and omega_n_rad_s, optional mass_g per object); several files "
                   "are joined")
    c.add_argument("--amp", type=float, default=None, help="plate amplitude A_p of the rows, degrees (default: "
                   "the CSV's a_p_deg column)")
    add_known_inputs(c, "", mass_default="the file's mass_g, else ")
    c.add_argument("--forward", default="lab", help="the forward model whose members read the sweeps")
    c.add_argument("--out", required=True, help="the calibration file to write (CAL.json)")


def run(args: argparse.Namespace) -> int:
    from plate_env.identify import lab_calibration_file as lcf
    from plate_env.surrogate.catalog import forward_model_names

    if args.forward not in forward_model_names():
        raise CliError(f"--forward {args.forward!r}: choose one of {forward_model_names()}")
    output_path(args.out, "--out")  # refused before the references are read, not after the calibration
    objects, omega_n, tables, masses = lcf.read_references(args.refs, a_p_deg=args.amp, max_rows=MAX_FIT_ROWS)
    lcf.check_references(objects, omega_n)
    given = {m for m in masses if m is not None}
    if len(given) > 1:
        raise CliError(f"the references have different masses {sorted(given)} g: one calibration holds for one mass")
    amps = sorted({float(a) for t in tables for a in t.a_p_deg})
    if len(amps) != 1:
        raise CliError(f"the references are at A_p {amps} deg: one calibration holds for one amplitude")
    known = known_inputs(args, mass_g=given.pop() if given else None)
    cal = lcf.calibrate(tables, omega_n, objects, amps[0], known, forward=args.forward)
    lcf.save(cal, args.out)
    s = cal.posterior.summary()
    top = max(s["member_weights"].items(), key=lambda kv: kv[1])
    print(f"calibration of {len(objects)} reference disc(s) at A_p = {amps[0]:g} deg written to {args.out}: "
          f"offset {s['a_mean']:+.2f}, slope {s['b_mean']:.2f}, scatter {s['sigma_mean']:.2f} (log omega_n), "
          f"member {top[0]} ({top[1]:.0%}); the feature line's weight {cal.feature_weight:.2f} (Lorentzian fits on "
          f"{sum(f is not None for f in cal.reference_features)} of {len(objects)} references)", flush=True)
    return 0
