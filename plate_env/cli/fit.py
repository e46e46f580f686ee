"""``plate-env fit``: fit a lab sweep (CSV) and estimate omega_n."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import TYPE_CHECKING

from plate_env.cli.options import MAX_FIT_ROWS, CliError, add_known_inputs, intervals, known_inputs, plot_path, say_plot
from plate_env.core.units import format_omega_pi
from plate_env.identify.api import METHODS

if TYPE_CHECKING:
    from plate_env.cli.options import Subparsers
    from plate_env.core.probe_table import ProbeTable
    from plate_env.identify.estimate import Estimate
    from plate_env.identify.estimators import CalibratedEstimator, Estimator


def add_parser(sub: Subparsers) -> None:
    """The ``fit`` command on the CLI's subparsers ``sub``."""
    f = sub.add_parser("fit", help="fit a lab sweep (CSV) and estimate omega_n")
    f.add_argument("csv", help="CSV with columns f_p_hz, omega_b_deg_s[, stderr_deg_s, a_p_deg, unstable]")
    f.add_argument("--amp", type=float, default=None, help="plate amplitude A_p of the rows, degrees (default: "
                   "the CSV's a_p_deg column)")
    add_known_inputs(f, "atlas method: ")
    f.add_argument("--method", default="atlas", choices=METHODS,
                   help="atlas: a forward model's posterior (default); lorentz: the paper's Eqs. 9-10")
    f.add_argument("--forward", default=None, help="atlas method: the forward model, 'lab' (data of unknown "
                   "origin: every physics and the unknown joint/contact values integrated over) or the simulator "
                   "that made the data, e.g. 'tilelink/pointmass'")
    f.add_argument("--physics", default=None, help="lorentz method: whose Eq. (10) calibration: lab (every model "
                   "pooled, default), tilelink (with --model), paper (the paper's coefficients)")
    f.add_argument("--model", default=None, help="lorentz method: tilelink model of the calibration (pointmass)")
    f.add_argument("--plot", default=None, help="write a PNG of data, fitted curve and posterior (after the results)")
    f.add_argument("--json", action="store_true", help="print one JSON document")
    f.add_argument("--calibration", default=None, help="a lab calibration (CAL.json from plate-env calibrate): read "
                   "the data through what the lab's reference discs taught")


#: From this many rows ``fit`` says on stderr what it computes and how long it took.
FIT_PROGRESS_ROWS = 200


#: Options of ``fit`` that only one method reads (refused with the other, never dropped silently).
FIT_METHOD_OPTIONS = {"atlas": ("forward", "bp", "mass_g", "diameter_mm"), "lorentz": ("physics", "model")}


def _fit_estimator(args: argparse.Namespace) -> Estimator:
    """``fit``'s :class:`~plate_env.identify.estimators.Estimator`, built once from the options: an option the chosen
    method does not read is refused (never dropped silently), so are a Lorentz line source that does not exist, a
    forward model that is not shipped and ``--calibration`` with another method than the default; ``args`` is read,
    not changed."""
    from plate_env.identify.estimators import READS_FORWARD_MODEL, ForwardName, make_estimator

    for method, names in FIT_METHOD_OPTIONS.items():
        given = [n for n in names if getattr(args, n) is not None]
        if method != args.method and given:
            opts = ", ".join("--" + n.replace("_", "-") for n in given)
            raise CliError(f"{opts} {'applies' if len(given) == 1 else 'apply'} to --method {method} only, not to "
                           f"--method {args.method}")
    # None is "not given"; an empty --forward '' or --physics '' is a value, refused below, not the default
    forward = "lab" if args.forward is None else args.forward
    physics = "lab" if args.physics is None else args.physics
    model = args.model or ("lab" if physics == "lab" else "pointmass")
    reads_forward = READS_FORWARD_MODEL[args.method]
    if not reads_forward and physics != "paper":
        from plate_env.identify.calibration import load_calibrations

        sources = sorted({k.rsplit("/", 1)[0] for k in load_calibrations()})
        if f"{physics}/{model}" not in sources:
            raise CliError(f"--physics {physics!r} --model {model!r}: no Eq. (10) calibration; calibrated: "
                           f"{', '.join(sources + ['paper'])}")
    known = known_inputs(args)
    if args.calibration is not None:
        if not reads_forward:
            raise CliError("--calibration reads the data through the atlas members: drop --method lorentz")
        if args.plot:
            raise CliError("--plot draws a forward model's curve; a calibrated fit has none: drop --plot or "
                           "--calibration")
        return make_estimator(known=known, calibration=args.calibration)
    if reads_forward:
        from plate_env.surrogate.catalog import forward_model_names

        if forward not in forward_model_names():
            raise CliError(f"--forward {forward!r}: choose one of {forward_model_names()}")
    return make_estimator(args.method, ForwardName(physics, model), known, forward=forward if reads_forward else None)


def _fit_report(est: Estimate, table: ProbeTable) -> list[str]:
    """An lmfit-like report of the per-amplitude Lorentzian fits."""
    out = []
    for amp, fit in est.fits.items():
        out.append(f"[[Fit A_p = {amp:g} deg]]  (Eq. 9, Levenberg-Marquardt)")
        if not fit.ok:
            out.append(f"    cannot fit: {fit.reason}")
            continue
        left = "; ".join(f"{n} {why}" for why, n in fit.left_out) or "none"
        out.append(f"    data points = {fit.n_used} used of {fit.n_used + sum(n for _, n in fit.left_out)}; left out: "
                   f"{left}")
        out.append(f"    R-squared   = {fit.r2:.4f}")
        for name, val, err, unit in (("omega_max", fit.omega_max, fit.stderr[0], "deg/s"),
                                     ("f0", fit.f0, fit.stderr[1], "Hz"), ("b", fit.b, fit.stderr[2], "Hz")):
            rel = f"({100 * err / abs(val):.2f}%)" if val else ""
            out.append(f"    {name:10s}= {val:10.4g} +/- {err:.4g} {unit} {rel}")
    return out


def uncalibrated_note(est: Estimate, hump: bool = False) -> str:
    """The line ``fit`` prints without a calibration: how far this fit's own 95 % interval reaches either side of
    its estimate (a factor; what it is on the paper's objects: ``experiments/results/forward_models_paper.md``);
    ``hump``: the probes show a measured resonance hump (a real plate's sweep?), so the paper's reference set is
    named too."""
    lo, hi = est.omega_n_ci95
    factor = max(hi / est.omega_n, est.omega_n / lo) if lo > 0 else math.inf
    paper = ("; these probes show a resonance hump, as a real plate's sweep does: at A_p = 3 deg the paper's "
             "reference set reads them too (--calibration paper)") if hump else ""
    return (f"uncalibrated: the interval carries the disagreement between the physics models (here a factor of "
            f"{factor:.3g} either way at 95 %); measure reference discs of known omega_n and run plate-env calibrate "
            f"to narrow it (docs/calibration.md){paper}")


def calibration_pointer(est: Estimate, table: ProbeTable) -> str | None:
    """The line ``fit`` prints after an uncalibrated atlas reading that gave no estimate (not a bound) of probes that
    look like a real plate's sweep (a measured resonance hump: :func:`plate_env.identify.estimators.hump_reason`):
    the calibrated readings that exist for such data. None otherwise (an estimate, a bound, or data with no hump:
    a calibration would refuse them too)."""
    from plate_env.identify.estimators import hump_reason

    if est.ok or est.bound is not None or hump_reason(table) is not None:
        return None
    return (f"these probes show a resonance hump, as a real plate's sweep does, that {est.forward!r} does not "
            "explain: read them through the paper's reference set (--calibration paper, A_p = 3 deg) or through "
            "reference discs of known omega_n measured on the same plate (plate-env calibrate; docs/calibration.md)")


def _read_fit_table(args: argparse.Namespace) -> ProbeTable:
    """``fit``'s CSV, refused past :data:`MAX_FIT_ROWS` rows (before any is parsed)."""
    from plate_env.core.probe_table import read_lab_csv

    return read_lab_csv(args.csv, a_p_deg=args.amp, max_rows=MAX_FIT_ROWS)


def _cmd_fit_calibrated(args: argparse.Namespace, estimator: CalibratedEstimator) -> int:
    from plate_env.identify import lab_calibration_file as lcf

    table = _read_fit_table(args)
    lcf.check_data(estimator.calibration, table, estimator.known or estimator.calibration.known)
    est = estimator.fit(table)
    if args.json:
        print(json.dumps({"file": str(args.csv), "calibrated": True, "calibration": str(args.calibration),
                          **est.to_dict()}), flush=True)
    elif est.ok:
        print(f"omega_n_hat = {est.omega_n:.2f} +- {est.omega_n_stderr:.2f} rad/s ({format_omega_pi(est.omega_n)}) "
              f"calibrated by {args.calibration}")
        print(intervals(est), flush=True)
    else:
        print(f"no estimate: {est.reason}", flush=True)
    return 0 if est.ok else 1


def run(args: argparse.Namespace) -> int:
    from plate_env.identify.estimators import AtlasEstimator, CalibratedEstimator

    estimator = _fit_estimator(args)
    if isinstance(estimator, CalibratedEstimator):
        return _cmd_fit_calibrated(args, estimator)
    plot = plot_path(args.plot) if args.plot else None
    table = _read_fit_table(args)
    incremental = isinstance(estimator, AtlasEstimator)  # the posterior and its check: say what is computed
    t0 = time.perf_counter()
    if incremental and len(table) >= FIT_PROGRESS_ROWS:
        from plate_env.identify.inference import distinct_probes

        print(f"fit: {len(table)} rows, {distinct_probes(table)} distinct (exact repeats computed once); computing "
              f"the posterior and its predictive check ...", file=sys.stderr, flush=True)
    est = estimator.fit(table)
    if incremental and len(table) >= FIT_PROGRESS_ROWS:
        print(f"fit: done in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    name = getattr(estimator, "name", None)  # the Lorentz method's line source (the atlas method reads --forward)
    physics, model = (name.physics, name.model) if name is not None else (None, None)
    if args.json:
        # what read the data, once: the atlas method's forward model ("forward"), or the Lorentz method's Eq. (10)
        # calibration ("physics", "model"; "forward" null); never the other method's unused options (issue 40 item 5)
        used = {} if name is None else {"physics": physics, "model": model}
        print(json.dumps({"file": str(args.csv), **used, "calibrated": False, **est.to_dict()}), flush=True)
    else:
        for line in _fit_report(est, table):
            print(line)
        if est.ok:
            print(f"omega_n_hat = {est.omega_n:.2f} +- {est.omega_n_stderr:.2f} rad/s "
                  f"({format_omega_pi(est.omega_n)}) by {est.method} on {est.forward or name}")
            print(intervals(est))
            if est.note:
                print(f"note: {est.note}")
            if est.alpha is not None:
                print(f"alpha_hat   = {math.degrees(est.alpha):.1f} +- {math.degrees(est.alpha_stderr):.1f} deg")
            if est.forward == "lab":
                from plate_env.identify.estimators import hump_reason

                print(uncalibrated_note(est, hump=hump_reason(table) is None))
        else:
            print(f"no estimate: {est.reason}")
            if incremental and (pointer := calibration_pointer(est, table)) is not None:
                print(pointer)
        sys.stdout.flush()
    if plot is not None:
        from plate_env.plotting import plot_fit

        plot_fit(table, est, str(plot), estimator.forward_model() if isinstance(estimator, AtlasEstimator) and est.ok
                 else None)
        say_plot(args, plot)
    return 0 if est.ok else 1
