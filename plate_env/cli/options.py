"""What several commands share: the user error, checked option types, and the options and values common to
``probe``, ``sweep``, ``identify``, ``fit`` and ``calibrate``."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from plate_env.core import checks
from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectSpec, preset
from plate_env.core.probe import WINDOW_RANGE_S
from plate_env.core.setup import (
    AMP_RANGE_RAD,
    B_P_RANGE_M,
    DIAMETER_RANGE_M,
    KNOWN_B_P_RANGE_M,
    MASS_RANGE_KG,
    PAPER_SETUP,
)
from plate_env.core.units import format_omega_pi, parse_omega_n
from plate_env.physics import PHYSICS_NAMES, ProbeSpec

if TYPE_CHECKING:
    from typing import TypeAlias

    from plate_env.identify.estimate import Estimate
    from plate_env.surrogate.conditioning import KnownInputs

    #: The CLI's subparsers, where each command module's ``add_parser`` adds its command.
    Subparsers: TypeAlias = argparse._SubParsersAction[argparse.ArgumentParser]

#: Most probes one sweep may ask for.
MAX_SWEEP_PROBES = 2000

#: Most rows ``fit`` reads, and ``calibrate`` over all its reference discs (what one sweep may make; the
#: posterior's cost grows with the rows).
MAX_FIT_ROWS = MAX_SWEEP_PROBES

#: The tile-link models ``--model`` takes, as help text (the list is plate_env.physics.tilelink.backend.MODELS, not
#: imported here: half a second of start-up; tests/test_hardening3_inputs.py checks the two agree).
TILELINK_MODELS_HELP = "pointmass, rigid, rigid_limit, rigid_fast"

#: The allowed mass at the edge, grams (plate_env.core.setup.MASS_RANGE_KG).
MASS_RANGE_G = tuple(round(x * 1e3, 9) for x in MASS_RANGE_KG)


class CliError(Exception):
    """A user error: printed as one line, exit code 2."""


def number_arg(check: Callable[..., Any], *args: Any, **kwargs: Any) -> Callable[[str], Any]:
    """An argparse ``type`` running ``check(name, value, ...)`` on the parsed number, so a bad value is refused
    while parsing, before any work, by a message naming the option and the allowed range."""
    integral = check is checks.integer

    def convert(text: str) -> Any:
        try:
            value = int(text) if integral else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if integral else 'a number'}") from None
        try:
            return check("value", value, *args, **kwargs)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc).replace(f"value = {value!r}", repr(text), 1)) from None

    return convert


def omega_n_arg(text: str) -> float:
    try:
        return parse_omega_n(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def plot_path(text: str) -> Path:
    """The file a ``--plot`` will write, checked before any work: its directory exists and is writable, it is not a
    directory, its extension is a format matplotlib writes (none: ``.png`` is added, and the final name printed)."""
    path = Path(text)
    if not text or path.is_dir():
        raise CliError(f"--plot {text!r} is a directory or empty; give a file name such as plot.png")
    if not path.suffix:
        path = path.with_name(path.name + ".png")
    from matplotlib.backend_bases import FigureCanvasBase

    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    if path.suffix[1:].lower() not in formats:
        raise CliError(f"--plot {text!r}: unknown image format {path.suffix!r}; use one of {', '.join(formats)}")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir() or not os.access(parent, os.W_OK):
        raise CliError(f"--plot {text!r}: directory {str(parent)!r} does not exist or is not writable")
    if path.exists() and not os.access(path, os.W_OK):
        raise CliError(f"--plot {text!r}: the file exists and is not writable")
    return path


def output_path(text: str, option: str) -> Path:
    """A file an option will write (``--markdown``, ``--csv``), checked before any work
    (:func:`plate_env.core.files.check_output`: not a directory or special file, its directory writable)."""
    from plate_env.core.files import check_output

    try:
        return check_output(text, option)
    except ValueError as exc:
        raise CliError(str(exc)) from None


def say_plot(args: argparse.Namespace, plot: Path) -> None:
    """Name the plot written (on stderr with --json, so stdout stays one JSON document)."""
    print(f"plot: {plot}", file=sys.stderr if args.json else sys.stdout)


def object_spec(args: argparse.Namespace) -> ObjectSpec:
    base = preset(args.object) if args.object else ObjectSpec(name="custom")
    changes: dict[str, float] = {}
    if args.omega_n is not None:
        changes["omega_n"] = args.omega_n
    if args.alpha is not None:
        changes["alpha"] = math.radians(args.alpha)
    if args.mass_g is not None:
        changes["mass"] = args.mass_g * 1e-3
    return base.with_(**changes) if changes else base


def physics_options(args: argparse.Namespace) -> dict[str, Any]:
    """Backend options from --model and --dt, refused where the backend has no such knob."""
    options: dict[str, Any] = {}
    if args.dt is not None:
        if args.physics == "atlas":
            raise CliError("--dt does not apply to --physics atlas (a tabulated response has no time step)")
        options["dt"] = args.dt
    if args.model:
        if args.physics == "pybullet":
            raise CliError("--model does not apply to --physics pybullet")
        options["model"] = args.model
    return options


def probe_spec(args: argparse.Namespace, obj: ObjectSpec, freq: float) -> ProbeSpec:
    motion = PlateMotion.from_paper(f_p_hz=freq, a_p_deg=args.amp, b_p_mm=args.bp)
    return ProbeSpec(obj=obj, motion=motion, settle_s=args.settle, measure_s=args.measure)


def add_object(p: argparse.ArgumentParser, true: str = "") -> None:
    from plate_env.core.objects import PRESETS

    custom = ObjectSpec(name="custom")  # what an option not given takes (the preset's value with --object)
    p.add_argument("--object", default=None, help=f"preset object: {', '.join(PRESETS)} (default: none, a custom "
                   "disc of the values below)")
    p.add_argument("--omega-n", default=None, type=omega_n_arg, help=f"{true}bending natural frequency, rad/s or "
                   f"e.g. 10pi (default: the preset's, else {format_omega_pi(custom.omega_n)})")
    p.add_argument("--alpha", type=number_arg(checks.real, 0.0, 90.0, open_lo=True, open_hi=True, unit="deg"),
                   default=None, help=f"{true}friction angle, degrees (default: the preset's, else "
                   f"{math.degrees(custom.alpha):.3g})")
    p.add_argument("--mass-g", type=number_arg(checks.real, *MASS_RANGE_G, unit="g"), default=None,
                   help=f"object mass, grams (default: the preset's, else {custom.mass * 1e3:.4g})")


def add_dt(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dt", type=number_arg(checks.real, 0.0, 0.01, open_lo=True, unit="s"), default=None,
                   help="time step, s (backend default if omitted; a warning above its measured stability limit)")


def add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--physics", default="tilelink", choices=PHYSICS_NAMES, help="physics backend")
    p.add_argument("--model", default=None, help=f"tilelink model ({TILELINK_MODELS_HELP}); atlas: whose atlas "
                   "(default: the physics' own, pointmass)")
    add_object(p)
    amp_deg = math.degrees(AMP_RANGE_RAD[1])
    p.add_argument("--amp", type=number_arg(checks.real, -amp_deg, amp_deg, unit="deg"), default=3.0,
                   help="plate angular amplitude A_p, degrees")
    p.add_argument("--bp", type=number_arg(checks.real, B_P_RANGE_M[0] * 1e3, B_P_RANGE_M[1] * 1e3, unit="mm"),
                   default=3.0, help="plate linear amplitude B_p, mm")
    window = number_arg(checks.real, *WINDOW_RANGE_S, unit="s")
    p.add_argument("--settle", type=window, default=ProbeSpec.settle_s, help="settling time after the ramp, s")
    p.add_argument("--measure", type=number_arg(checks.real, *WINDOW_RANGE_S, open_lo=True, unit="s"),
                   default=ProbeSpec.measure_s, help="measurement window, s (rounded to whole plate periods, at "
                   "least 2)")
    add_dt(p)
    p.add_argument("--json", action="store_true", help="print one JSON document")


def add_known_inputs(p: argparse.ArgumentParser, what: str, mass_default: str = "") -> None:
    """``--bp``, ``--mass-g``, ``--diameter-mm``: what the lab knows, in the allowed ranges of
    :mod:`plate_env.core.setup`; default None (the command fills in :data:`PAPER_SETUP`'s values)."""
    p.add_argument("--bp", type=number_arg(checks.real, *(round(x * 1e3, 9) for x in KNOWN_B_P_RANGE_M), unit="mm"),
                   default=None, help=f"{what}plate linear amplitude B_p, mm (known input; default "
                   f"{PAPER_SETUP.b_p_mm:g})")
    p.add_argument("--mass-g", type=number_arg(checks.real, *MASS_RANGE_G, unit="g"), default=None,
                   help=f"{what}the disc's mass, grams (known input; default {mass_default}{PAPER_SETUP.mass_g:g})")
    p.add_argument("--diameter-mm", type=number_arg(checks.real, *(round(x * 1e3, 9) for x in DIAMETER_RANGE_M),
                                                    unit="mm"),
                   default=None, help=f"{what}the disc's diameter, mm (known input; default "
                   f"{PAPER_SETUP.diameter_mm:g})")


def known_inputs(args: argparse.Namespace, mass_g: float | None = None) -> KnownInputs:
    """The known inputs given as ``--bp``, ``--mass-g``, ``--diameter-mm``; each one not given is ``PAPER_SETUP``'s
    (the mass: ``mass_g`` first, e.g. a references file's)."""
    from plate_env.surrogate.conditioning import KnownInputs

    def given(value: float | None, default: float) -> float:
        return default if value is None else value

    return KnownInputs(b_p=given(args.bp, PAPER_SETUP.b_p_mm) * 1e-3,
                       mass=given(args.mass_g, given(mass_g, PAPER_SETUP.mass_g)) * 1e-3,
                       diameter=given(args.diameter_mm, PAPER_SETUP.diameter_mm) * 1e-3)


def intervals(est: Estimate) -> str:
    """The 68 % and 95 % intervals of omega_n, rad/s and in units of pi."""
    (a, b), (c, d) = est.omega_n_ci68, est.omega_n_ci95
    return (f"              68 % interval {a:.2f}-{b:.2f} rad/s ({a / math.pi:.2f}-{b / math.pi:.2f} pi), "
            f"95 % interval {c:.2f}-{d:.2f} rad/s ({c / math.pi:.2f}-{d / math.pi:.2f} pi)")
