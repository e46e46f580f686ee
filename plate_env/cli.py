"""``plate-env`` command line: identify, probe, sweep, fit, calibrate, bench, build. ``--json`` on every command
prints one JSON document."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from plate_env.build.commands import add_build_parser, run_build
from plate_env.core import checks
from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectSpec, preset
from plate_env.core.probe import MIN_PROBE_FREQ_HZ, WINDOW_RANGE_S
from plate_env.core.setup import (
    AMP_RANGE_RAD,
    B_P_RANGE_M,
    DEFAULT_MAX_PROBES,
    DIAMETER_RANGE_M,
    FREQ_RANGE_HZ,
    KNOWN_B_P_RANGE_M,
    MASS_RANGE_KG,
    MAX_PROBES_RANGE,
    PAPER_SETUP,
    SEED_RANGE,
)
from plate_env.core.streams import stdout_to_stderr
from plate_env.core.units import format_omega_pi, parse_omega_n
from plate_env.identify.api import METHODS
from plate_env.physics import PHYSICS_NAMES, ProbeSpec, make_physics
from plate_env.physics.interface import refuse_early
from plate_env.run.executor import BackendSpec, add_executor_argument, make_executor

#: Most probes one sweep may ask for.
MAX_SWEEP_PROBES = 2000


class CliError(Exception):
    """A user error: printed as one line, exit code 2."""


def _arg(check: Callable, *args, **kwargs) -> Callable[[str], object]:
    """An argparse ``type`` running ``check(name, value, ...)`` on the parsed number, so a bad value is refused
    while parsing, before any work, by a message naming the option and the allowed range."""
    integral = check is checks.integer

    def convert(text: str):
        try:
            value = int(text) if integral else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if integral else 'a number'}") from None
        try:
            return check("value", value, *args, **kwargs)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc).replace(f"value = {value!r}", repr(text), 1)) from None

    return convert


def _omega_n_arg(text: str) -> float:
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


def parse_freqs(text: str) -> np.ndarray:
    """``"10:40:1"`` (start:stop:step, inclusive) or ``"12,18,25"`` -> frequencies in Hz.

    The probe count is checked (at most :data:`MAX_SWEEP_PROBES`) before any array is made."""
    lo, hi = MIN_PROBE_FREQ_HZ, FREQ_RANGE_HZ[1]
    try:
        parts = [float(p) for p in text.split(":" if ":" in text else ",") if ":" in text or p.strip()]
        if ":" in text and len(parts) != 3:
            raise ValueError
    except ValueError:
        raise CliError(f"--freqs {text!r}: expected start:stop:step (e.g. 10:40:1) or a list like 12,18,25") from None
    if ":" in text:
        start, stop, step = parts
        if not all(math.isfinite(x) for x in parts) or not (lo <= start <= stop <= hi):
            raise CliError(f"--freqs {text!r}: start and stop must satisfy {lo:g} <= start <= stop <= {hi:g} Hz")
        if not step > 0:
            raise CliError(f"--freqs {text!r}: the step must be positive")
        span = (stop - start) / step  # inf for a subnormal step (1e-320): refused, not an overflow
        count = math.floor(span + 1e-6) + 1 if math.isfinite(span) else math.inf
        if count > MAX_SWEEP_PROBES:
            raise CliError(f"--freqs {text!r}: {count:.4g} probes; at most {MAX_SWEEP_PROBES} per sweep "
                           f"(use a larger step)")
        return start + step * np.arange(count)
    freqs = np.array(parts)
    if freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs < lo) or np.any(freqs > hi):
        raise CliError(f"--freqs {text!r}: frequencies must lie in [{lo:g}, {hi:g}] Hz")
    if freqs.size > MAX_SWEEP_PROBES:
        raise CliError(f"--freqs {text!r}: {freqs.size} probes; at most {MAX_SWEEP_PROBES} per sweep")
    return freqs


def _object(args: argparse.Namespace) -> ObjectSpec:
    base = preset(args.object) if args.object else ObjectSpec(name="custom")
    changes: dict = {}
    if args.omega_n is not None:
        changes["omega_n"] = args.omega_n
    if args.alpha is not None:
        changes["alpha"] = math.radians(args.alpha)
    if args.mass_g is not None:
        changes["mass"] = args.mass_g * 1e-3
    return base.with_(**changes) if changes else base


def _physics_options(args: argparse.Namespace) -> dict:
    """Backend options from --model and --dt, refused where the backend has no such knob."""
    options: dict = {}
    if args.dt is not None:
        if args.physics == "atlas":
            raise CliError("--dt does not apply to --physics atlas (a tabulated response has no time step)")
        options["dt"] = args.dt
    if args.model:
        if args.physics == "pybullet":
            raise CliError("--model does not apply to --physics pybullet")
        options["model"] = args.model
    return options


def _physics(args: argparse.Namespace):
    return make_physics(args.physics, **_physics_options(args))


def _spec(args: argparse.Namespace, obj: ObjectSpec, freq: float) -> ProbeSpec:
    motion = PlateMotion.from_paper(f_p_hz=freq, a_p_deg=args.amp, b_p_mm=args.bp)
    return ProbeSpec(obj=obj, motion=motion, settle_s=args.settle, measure_s=args.measure)


def _add_object(p: argparse.ArgumentParser, true: str = "") -> None:
    from plate_env.core.objects import PRESETS

    custom = ObjectSpec(name="custom")  # what an option not given takes (the preset's value with --object)
    p.add_argument("--object", default=None, help=f"preset object: {', '.join(PRESETS)} (default: none, a custom "
                   "disc of the values below)")
    p.add_argument("--omega-n", default=None, type=_omega_n_arg, help=f"{true}bending natural frequency, rad/s or "
                   f"e.g. 10pi (default: the preset's, else {format_omega_pi(custom.omega_n)})")
    p.add_argument("--alpha", type=_arg(checks.real, 0.0, 90.0, open_lo=True, open_hi=True, unit="deg"),
                   default=None, help=f"{true}friction angle, degrees (default: the preset's, else "
                   f"{math.degrees(custom.alpha):.3g})")
    p.add_argument("--mass-g", type=_arg(checks.real, *MASS_RANGE_G, unit="g"), default=None,
                   help=f"object mass, grams (default: the preset's, else {custom.mass * 1e3:.4g})")


def _add_dt(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dt", type=_arg(checks.real, 0.0, 0.01, open_lo=True, unit="s"), default=None,
                   help="time step, s (backend default if omitted; a warning above its measured stability limit)")


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--physics", default="tilelink", choices=PHYSICS_NAMES, help="physics backend")
    p.add_argument("--model", default=None, help=f"tilelink model ({TILELINK_MODELS_HELP}); atlas: whose atlas "
                   "(default: the physics' own, pointmass)")
    _add_object(p)
    amp_deg = math.degrees(AMP_RANGE_RAD[1])
    p.add_argument("--amp", type=_arg(checks.real, -amp_deg, amp_deg, unit="deg"), default=3.0,
                   help="plate angular amplitude A_p, degrees")
    p.add_argument("--bp", type=_arg(checks.real, B_P_RANGE_M[0] * 1e3, B_P_RANGE_M[1] * 1e3, unit="mm"),
                   default=3.0, help="plate linear amplitude B_p, mm")
    window = _arg(checks.real, *WINDOW_RANGE_S, unit="s")
    p.add_argument("--settle", type=window, default=ProbeSpec.settle_s, help="settling time after the ramp, s")
    p.add_argument("--measure", type=_arg(checks.real, *WINDOW_RANGE_S, open_lo=True, unit="s"),
                   default=ProbeSpec.measure_s, help="measurement window, s (rounded to whole plate periods, at "
                   "least 2)")
    _add_dt(p)
    p.add_argument("--json", action="store_true", help="print one JSON document")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="plate-env", description=__doc__)
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("probe", help="run one probe and print omega_B")
    _add_common(p)
    p.add_argument("--freq", type=_arg(checks.real, MIN_PROBE_FREQ_HZ, FREQ_RANGE_HZ[1], unit="Hz"), required=True,
                   help="plate frequency f_p, Hz")
    s = sub.add_parser("sweep", help="run a batched frequency sweep")
    _add_common(s)
    s.add_argument("--freqs", default="10:40:1", help="start:stop:step or a comma list, Hz")
    s.add_argument("--plot", default=None, help="write a PNG of omega_B vs f_p (after the results are printed)")
    s.add_argument("--csv", default=None, help="also write the probes as a CSV that `plate-env fit` reads")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--cache", default=None, help="JSON-lines file: finished chunks are appended, a rerun resumes")
    s.add_argument("--chunk", type=_arg(checks.integer, 1, MAX_SWEEP_PROBES), default=8,
                   help="probes per chunk (a unit of work and of persistence)")
    add_executor_argument(s)
    i = sub.add_parser("identify", help="identify a hidden object with a probing agent (the main job)")
    i.add_argument("--agent", default="bayes", choices=_agent_names(), help="the probing agent")
    i.add_argument("--physics", default="tilelink", choices=PHYSICS_NAMES, help="physics backend")
    i.add_argument("--model", default=None, help=f"tilelink model ({TILELINK_MODELS_HELP}; default: pointmass)")
    _add_object(i, true="true ")
    i.add_argument("--seed", type=_arg(checks.integer, *SEED_RANGE), default=0,
                   help="seed of the episode (placement, camera noise)")
    i.add_argument("--bp", type=_arg(checks.real, B_P_RANGE_M[0] * 1e3, B_P_RANGE_M[1] * 1e3, unit="mm"),
                   default=3.0, help="plate linear amplitude B_p, mm (known input: the physics runs it, the "
                   "forward model is conditioned on it)")
    i.add_argument("--max-probes", type=_arg(checks.integer, *MAX_PROBES_RANGE), default=DEFAULT_MAX_PROBES,
                   help="probe budget")
    i.add_argument("--target", type=_arg(checks.real, 0.0, 1.0, open_lo=True, open_hi=True), default=None,
                   help="bayes only: stop at this relative posterior std of omega_n (a fraction; default: none, "
                   "the probe budget alone stops it)")
    _add_dt(i)
    i.add_argument("--plot", default=None, help="write a PNG of the probes, fit and estimate (after the results)")
    i.add_argument("--json", action="store_true", help="print one JSON document")
    _add_bench(sub)
    f = sub.add_parser("fit", help="fit a lab sweep (CSV) and estimate omega_n")
    f.add_argument("csv", help="CSV with columns f_p_hz, omega_b_deg_s[, stderr_deg_s, a_p_deg, unstable]")
    f.add_argument("--amp", type=float, default=None, help="plate amplitude A_p of the rows, degrees (default: "
                   "the CSV's a_p_deg column)")
    _add_known_inputs(f, "atlas method: ")
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
    _add_calibrate(sub)
    _add_cache(sub)
    add_build_parser(sub)
    _set_formatter(parser)  # --help shows every default, in every subcommand (build's too)
    return parser


def _set_formatter(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = _DefaultsFormatter
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for p in action.choices.values():
                _set_formatter(p)


#: The tile-link models ``--model`` takes, as help text (the list is plate_env.physics.tilelink.backend.MODELS, not
#: imported here: half a second of start-up; tests/test_hardening3_inputs.py checks the two agree).
TILELINK_MODELS_HELP = "pointmass, rigid, rigid_limit, rigid_fast"


class _DefaultsFormatter(argparse.HelpFormatter):
    """Help that names each option's default (none shown for flags and options without one)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        d = action.default  # by identity: a default of 0 or 0.0 is shown (0 == False hid --seed's, issue 40)
        shown = (action.option_strings and not (d is None or d is False or d is argparse.SUPPRESS or d == [])
                 and not isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)))
        if shown and "%(default)" not in text:
            text += " (default: %(default)s)"
        return text


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("plate-env")
    except PackageNotFoundError:
        return "unknown (not installed)"


#: Where ``bench`` keeps finished episodes unless told otherwise (a rerun resumes from there).
BENCH_CACHE_DIR = ".plate_env_bench"


def _agent_names() -> tuple[str, ...]:
    # the seam: the CLI is the application layer, the only module of plate_env that imports the agents
    from plate_env_agents import AGENT_NAMES

    return AGENT_NAMES
#: The allowed mass at the edge, grams (plate_env.core.setup.MASS_RANGE_KG).
MASS_RANGE_G = tuple(round(x * 1e3, 9) for x in MASS_RANGE_KG)


def _add_bench(sub) -> None:
    b = sub.add_parser("bench", help="score agents on a versioned suite: error against probing seconds, intervals")
    b.add_argument("--suite", nargs="+", default=["atlas-v0"], help="suite name (atlas-v0, tilelink-v0, "
                   "pybullet-v0, faithful-v0, misspec_pointmass-v0, misspec_faithful-v0, misspec_pybullet-v0) or a "
                   "suite .json file; several: every agent on every suite, and a table of agents against suites")
    b.add_argument("--agent", action="extend", nargs="+", required=True,
                   help="one or more agents: bayes, grid, coarse_to_fine, ppo (options: grid:n=30,method=atlas), "
                        "path/to/file.py:MyAgent, sb3:model.zip (sb3:td3:model.zip: ppo, a2c, sac, td3, ddpg)")
    b.add_argument("--budgets", default=None, help="probing budgets to score, simulated s, comma list (default: the "
                   "suite's; each at most its largest)")
    b.add_argument("--limit", type=_arg(checks.integer, 1, 100_000), default=None,
                   help="only the first N objects (a quick look, not the suite's result; default: all)")
    b.add_argument("--cache", default=None, help=f"JSON-lines file of finished episodes, a rerun resumes (default "
                   f"{BENCH_CACHE_DIR}/<suite>.jsonl)")
    b.add_argument("--no-cache", action="store_true", help="keep no episodes on disk")
    b.add_argument("--chunk", type=_arg(checks.integer, 1, 1000), default=2, help="episodes per task")
    b.add_argument("--markdown", default=None, help="also write the leaderboard, under a title and the suite's "
                   "description, to this markdown file")
    b.add_argument("--plot", default=None, help="write the error curves (after the results are printed)")
    b.add_argument("--no-progress", action="store_true", help="no progress bar")
    b.add_argument("--json", action="store_true", help="print one JSON document")
    add_executor_argument(b)


def _nulled(obj, path: str, nulled: list[str]):
    if isinstance(obj, float) and not math.isfinite(obj):
        nulled.append(path)
        return None
    if isinstance(obj, dict):
        return {k: _nulled(v, f"{path}.{k}" if path else str(k), nulled) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_nulled(v, f"{path}[{i}]", nulled) for i, v in enumerate(obj)]
    return obj


def strict_json(doc: dict) -> str:
    """``doc`` as strict JSON (RFC 8259: no ``Infinity`` or ``NaN``, which Python's json writes and most parsers
    refuse): a non-finite number becomes ``null`` and its path is listed under ``"non_finite"`` (e.g. an error of
    an agent with no estimate, which is infinite)."""
    nulled: list[str] = []
    out = _nulled(doc, "", nulled)
    if nulled:
        out["non_finite"] = nulled
    return json.dumps(out, allow_nan=False)


def _bench_note(args: argparse.Namespace, suites: Sequence[str]) -> str:
    """How to regenerate a leaderboard (the command, the cache it resumes from) and the machine's load."""
    import shlex

    cmd = ["plate-env", "bench", "--suite", *suites, "--agent", *args.agent]
    cmd += ["--limit", str(args.limit)] * (args.limit is not None) + ["--budgets", args.budgets] * bool(args.budgets)
    try:
        load = Path("/proc/loadavg").read_text().split()[0]
    except OSError:
        load = "?"
    return (f"Regenerate: `{shlex.join(cmd)}` (finished episodes are kept in the cache, a rerun resumes). Wall "
            f"seconds per decision were measured at load {load}, noisy.")


def _parse_budgets(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise CliError(f"--budgets {text!r}: a comma list of simulated seconds, e.g. 10,20,40") from None


def _cmd_bench(args: argparse.Namespace) -> int:
    import functools

    from plate_env import bench as benchmark
    from plate_env.bench.suites import load_suite
    from plate_env.run.executor import check_executor_name, default_local

    # the seam: the CLI is the application layer, the only module of plate_env that imports the agents
    from plate_env_agents import load_agent

    if len(set(args.suite)) != len(args.suite):
        raise CliError(f"--suite: each suite once, got {args.suite}")
    suites = [load_suite(name) for name in args.suite]
    several = len(suites) > 1
    if several and args.cache:
        raise CliError("--cache names one suite's file: with several suites each keeps its own default cache "
                       f"({BENCH_CACHE_DIR}/<suite>.jsonl); drop --cache or run one suite")
    if several and args.plot:
        raise CliError("--plot draws one suite's error curves: run one suite with --plot")
    budgets = {s.name: benchmark.check_budgets(s, _parse_budgets(args.budgets)) for s in suites}
    plot = plot_path(args.plot) if args.plot else None
    markdown = output_path(args.markdown, "--markdown") if args.markdown else None
    check_executor_name(args.executor)
    if len(set(args.agent)) != len(args.agent):
        raise CliError(f"--agent: each agent once, got {args.agent}")
    agents = {spec: load_agent(spec) for spec in args.agent}  # every spec checked before any episode runs
    boards = {}
    for suite in suites:
        where = args.executor if args.executor not in (None, "local") else default_local(
            BackendSpec.of(suite.physics, **dict(suite.env_kwargs.get("physics_options") or {})))
        cache = None if args.no_cache else (args.cache or str(Path(BENCH_CACHE_DIR) / f"{suite.name}.jsonl"))
        runs = []
        for spec, agent in agents.items():
            what = agent if where == "inprocess" else functools.partial(load_agent, spec)
            try:
                # what agents and libraries print while episodes run (Python's print, C code and child processes
                # on fd 1, Ray's worker-death lines) goes to stderr: stdout keeps the one result document
                with stdout_to_stderr():
                    runs.append(benchmark.evaluate(what, suite, label=spec, budgets_s=budgets[suite.name],
                                                   executor=args.executor, cache=cache, limit=args.limit,
                                                   chunk=args.chunk, progress=not (args.json or args.no_progress)))
            except benchmark.BenchInterrupted as exc:
                kept = (f"kept in {exc.cache}; rerun the same command to resume" if exc.cache else
                        "not kept (--no-cache)")
                print(f"plate-env bench: interrupted during {spec} on {suite.name} after {exc.finished} episodes "
                      f"({kept})", file=sys.stderr)
                return 130
        boards[suite.name] = benchmark.board(runs, budgets[suite.name])
    note = _bench_note(args, args.suite)
    if not several:
        suite, b = suites[0], boards[suites[0].name]
        text = benchmark.leaderboard_markdown(b["summaries"], b["paired"], b["leader"], note=note)
        if args.markdown:
            text = f"# Leaderboard: {suite.name}\n\n{suite.description}\n\n{text}"
        document = {"suite": suite.name, "suite_sha256": suite.sha256, "budgets_s": list(budgets[suite.name]),
                    **benchmark.board_to_dict(b)}
    else:
        top = min(max(v) for v in budgets.values())
        text = benchmark.matrix_markdown({n: b["summaries"] for n, b in boards.items()}, top, note=note)
        for suite in suites:
            b = boards[suite.name]
            text += (f"\n## {suite.name}\n\n{suite.description}\n\n"
                     + benchmark.leaderboard_markdown(b["summaries"], b["paired"], b["leader"], detail=False))
        if args.markdown:
            text = "# Agents against suites: " + ", ".join(s.name for s in suites) + "\n\n" + text
        document = {"matrix_budget_s": top, "suites": [
            {"suite": s.name, "suite_sha256": s.sha256, "budgets_s": list(budgets[s.name]),
             **benchmark.board_to_dict(boards[s.name])} for s in suites]}
    if args.json:
        print(strict_json(document), flush=True)
    else:
        print(text, flush=True)
    if markdown is not None:
        from plate_env.core.files import write_text_atomic

        write_text_atomic(markdown, text, "--markdown")
    if plot is not None:
        from plate_env.plotting import plot_curves

        plot_curves(boards[suites[0].name]["summaries"], str(plot))
        _say_plot(args, plot)
    return 0


def _cmd_probe(args: argparse.Namespace) -> int:
    obj = _object(args)
    spec = _spec(args, obj, args.freq)
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


def _print_sweep(args: argparse.Namespace, obj: ObjectSpec, results: list, interrupted: bool) -> None:
    if args.json:
        print(json.dumps({"physics": args.physics, "object": obj.name, "interrupted": interrupted,
                          "probes": [r.to_dict() for r in results]}), flush=True)
        return
    print(f"{args.physics}: omega_n={format_omega_pi(obj.omega_n)} rad/s alpha={math.degrees(obj.alpha):.1f} deg "
          f"A_p={args.amp:g} deg B_p={args.bp:g} mm")
    print(f"{'f_p [Hz]':>9} {'omega_B [deg/s]':>16} {'stderr':>8}  state  (an unstable probe has no omega_B: -)")
    for r in results:
        if r.unstable:  # one rule: what it turned at before it slipped or broke is not a steady omega_B
            print(f"{r.spec.motion.freq_hz:9.2f} {'-':>16} {'-':>8}  unstable: {r.reason}")
        else:
            print(f"{r.spec.motion.freq_hz:9.2f} {r.omega_b_deg_s:16.1f} {r.stderr_deg_s:8.1f}  stable")
    print(f"{sum(r.sim_s for r in results):.1f} s simulated in {sum(r.wall_s for r in results):.2f} s wall",
          flush=True)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from plate_env.run.sweeps import SweepInterrupted, run_cached

    obj = _object(args)
    freqs = parse_freqs(args.freqs)
    plot = plot_path(args.plot) if args.plot else None
    csv_out = output_path(args.csv, "--csv") if args.csv else None
    specs = [_spec(args, obj, f) for f in freqs]
    backend = BackendSpec.of(args.physics, **_physics_options(args))
    built = backend.build()  # bad options and probes the backend cannot run: refused here, before any worker starts
    try:
        refuse_early(built, specs)
    finally:
        built.close()
    interrupted = False
    # what the physics, pool or Ray workers print (Ray's worker-death lines included) goes to stderr; the workers
    # started here inherit that fd 1. The results are printed after the block.
    with stdout_to_stderr():
        try:
            executor = make_executor(args.executor, backend)
        except ImportError as exc:
            raise CliError(str(exc)) from None
        try:
            results = run_cached(backend, specs, args.cache, chunk=args.chunk,
                                 progress=not (args.json or args.no_progress), desc="sweep", executor=executor)
        except SweepInterrupted as exc:  # Ctrl-C: the finished probes are printed (and cached with --cache)
            results, interrupted = exc.results, True
        finally:
            executor.close()
    _print_sweep(args, obj, results, interrupted)
    if csv_out is not None and results:
        from plate_env.core.probe_table import ProbeTable, write_lab_csv

        write_lab_csv(ProbeTable.from_results(results), csv_out)
        print(f"csv: {csv_out}", file=sys.stderr if args.json else sys.stdout)
    if interrupted:
        print(f"plate-env sweep: interrupted after {len(results)} of {len(specs)} probes (printed above)",
              file=sys.stderr)
        return 130
    if plot is not None:
        from plate_env.plotting import plot_sweep

        plot_sweep(results, str(plot), title=f"{args.physics}: omega_n={format_omega_pi(obj.omega_n)} rad/s, "
                   f"alpha={math.degrees(obj.alpha):.1f} deg, A_p={args.amp:g} deg")
        _say_plot(args, plot)
    return 0


def _say_plot(args: argparse.Namespace, plot: Path) -> None:
    """Name the plot written (on stderr with --json, so stdout stays one JSON document)."""
    print(f"plot: {plot}", file=sys.stderr if args.json else sys.stdout)


def _fit_report(est, table) -> list[str]:
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


#: Most rows ``fit`` reads, and ``calibrate`` over all its reference discs (what one sweep may make; the
#: posterior's cost grows with the rows).
MAX_FIT_ROWS = MAX_SWEEP_PROBES
#: From this many rows ``fit`` says on stderr what it computes and how long it took.
FIT_PROGRESS_ROWS = 200
#: ``fit``'s known inputs when not given (the paper's set-up and disc).
FIT_KNOWN = {"bp": PAPER_SETUP.b_p_mm, "mass_g": PAPER_SETUP.mass_g, "diameter_mm": PAPER_SETUP.diameter_mm}
#: Options of ``fit`` that only one method reads (refused with the other, never dropped silently).
FIT_METHOD_OPTIONS = {"atlas": ("forward", "bp", "mass_g", "diameter_mm"), "lorentz": ("physics", "model")}


def _fit_estimator(args: argparse.Namespace):
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
    known = _known_inputs(args)
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


def _add_known_inputs(p: argparse.ArgumentParser, what: str, mass_default: str = "") -> None:
    """``--bp``, ``--mass-g``, ``--diameter-mm``: what the lab knows, in the allowed ranges of
    :mod:`plate_env.core.setup`; default None (the command fills in :data:`PAPER_SETUP`'s values)."""
    p.add_argument("--bp", type=_arg(checks.real, *(round(x * 1e3, 9) for x in KNOWN_B_P_RANGE_M), unit="mm"),
                   default=None, help=f"{what}plate linear amplitude B_p, mm (known input; default "
                   f"{PAPER_SETUP.b_p_mm:g})")
    p.add_argument("--mass-g", type=_arg(checks.real, *MASS_RANGE_G, unit="g"), default=None,
                   help=f"{what}the disc's mass, grams (known input; default {mass_default}{PAPER_SETUP.mass_g:g})")
    p.add_argument("--diameter-mm", type=_arg(checks.real, *(round(x * 1e3, 9) for x in DIAMETER_RANGE_M), unit="mm"),
                   default=None, help=f"{what}the disc's diameter, mm (known input; default "
                   f"{PAPER_SETUP.diameter_mm:g})")


def _add_calibrate(sub) -> None:
    c = sub.add_parser("calibrate", help="learn a lab calibration from reference discs of known omega_n")
    c.add_argument("refs", nargs="+", help="the reference discs: SWEEP.csv=OMEGA (one disc's sweep as `sweep --csv` "
                   "writes it, its known omega_n in rad/s or e.g. 10pi; named after the file) or REFS.csv (several "
                   "discs: the fit columns plus object and omega_n_rad_s, optional mass_g per object); several files "
                   "are joined")
    c.add_argument("--amp", type=float, default=None, help="plate amplitude A_p of the rows, degrees (default: "
                   "the CSV's a_p_deg column)")
    _add_known_inputs(c, "", mass_default="the file's mass_g, else ")
    c.add_argument("--forward", default="lab", help="the forward model whose members read the sweeps")
    c.add_argument("--out", required=True, help="the calibration file to write (CAL.json)")


def _cmd_calibrate(args: argparse.Namespace) -> int:
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
    known = _known_inputs(args, mass_g=given.pop() if given else None)
    cal = lcf.calibrate(tables, omega_n, objects, amps[0], known, forward=args.forward)
    lcf.save(cal, args.out)
    s = cal.posterior.summary()
    top = max(s["member_weights"].items(), key=lambda kv: kv[1])
    print(f"calibration of {len(objects)} reference disc(s) at A_p = {amps[0]:g} deg written to {args.out}: "
          f"offset {s['a_mean']:+.2f}, slope {s['b_mean']:.2f}, scatter {s['sigma_mean']:.2f} (log omega_n), "
          f"member {top[0]} ({top[1]:.0%})", flush=True)
    return 0


def uncalibrated_note(est) -> str:
    """The line ``fit`` prints without a calibration: how far this fit's own 95 % interval reaches either side of
    its estimate (a factor; what it is on the paper's objects: ``experiments/results/forward_models_paper.md``)."""
    lo, hi = est.omega_n_ci95
    factor = max(hi / est.omega_n, est.omega_n / lo) if lo > 0 else math.inf
    return (f"uncalibrated: the interval carries the disagreement between the physics models (here a factor of "
            f"{factor:.3g} either way at 95 %); measure reference discs of known omega_n and run plate-env calibrate "
            f"to narrow it (docs/calibration.md)")


def _known_inputs(args: argparse.Namespace, mass_g: float | None = None):
    """The known inputs given as ``--bp``, ``--mass-g``, ``--diameter-mm``; each one not given is ``PAPER_SETUP``'s
    (the mass: ``mass_g`` first, e.g. a references file's)."""
    from plate_env.surrogate.conditioning import KnownInputs

    def given(value, default):
        return default if value is None else value

    return KnownInputs(b_p=given(args.bp, PAPER_SETUP.b_p_mm) * 1e-3,
                       mass=given(args.mass_g, given(mass_g, PAPER_SETUP.mass_g)) * 1e-3,
                       diameter=given(args.diameter_mm, PAPER_SETUP.diameter_mm) * 1e-3)


def _read_fit_table(args: argparse.Namespace):
    """``fit``'s CSV, refused past :data:`MAX_FIT_ROWS` rows (before any is parsed)."""
    from plate_env.core.probe_table import read_lab_csv

    return read_lab_csv(args.csv, a_p_deg=args.amp, max_rows=MAX_FIT_ROWS)


def _cmd_fit_calibrated(args: argparse.Namespace, estimator) -> int:
    from plate_env.identify import lab_calibration_file as lcf

    table = _read_fit_table(args)
    lcf.check_data(estimator.calibration, table, estimator.known)
    est = estimator.fit(table)
    if args.json:
        print(json.dumps({"file": str(args.csv), "calibrated": True, "calibration": str(args.calibration),
                          **est.to_dict()}), flush=True)
    elif est.ok:
        print(f"omega_n_hat = {est.omega_n:.2f} +- {est.omega_n_stderr:.2f} rad/s ({format_omega_pi(est.omega_n)}) "
              f"calibrated by {args.calibration}")
        print(_intervals(est), flush=True)
    else:
        print(f"no estimate: {est.reason}", flush=True)
    return 0 if est.ok else 1


def _cmd_fit(args: argparse.Namespace) -> int:
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
            print(_intervals(est))
            if est.note:
                print(f"note: {est.note}")
            if est.alpha is not None:
                print(f"alpha_hat   = {math.degrees(est.alpha):.1f} +- {math.degrees(est.alpha_stderr):.1f} deg")
            if est.forward == "lab":
                print(uncalibrated_note(est))
        else:
            print(f"no estimate: {est.reason}")
        sys.stdout.flush()
    if plot is not None:
        from plate_env.plotting import plot_fit

        plot_fit(table, est, str(plot), estimator.forward_model() if incremental and est.ok else None)
        _say_plot(args, plot)
    return 0 if est.ok else 1


def _cmd_identify(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from plate_env.env.episode import run_episode

    # the seam: the CLI is the application layer, the only module of plate_env that imports the agents
    # (tests/test_code_health.py keeps it so); the library core below it does not
    from plate_env_agents import make_agent

    if args.target is not None and args.agent != "bayes":
        raise CliError(f"--target applies to --agent bayes only (its stopping rule), not to --agent {args.agent}")
    obj = _object(args)
    plot = plot_path(args.plot) if args.plot else None
    agent = make_agent(args.agent, **({} if args.target is None else {"target_rel": args.target}))
    env_kw = dict(physics=args.physics, physics_options=_physics_options(args), max_probes=args.max_probes,
                  b_p_mm=args.bp)
    if args.physics == "pybullet":
        env_kw["method"] = "lorentz"
    env = gym.make("PlateRotation-v0", **env_kw)

    def show(k: int, p: dict) -> None:
        state = f"unstable: {p['reason']}" if p["unstable"] else f"{p['omega_b_deg_s']:7.1f} deg/s"
        print(f"probe {k:2d}: f_p = {p['f_p_hz']:6.2f} Hz  A_p = {p['a_p_deg']:4.1f} deg  "
              f"{p['sim_s']:.2f} s simulated  -> {state}", flush=True)

    try:
        # with --json, what the agent and the physics print goes to stderr (the text mode shows probes as they end)
        with stdout_to_stderr() if args.json else contextlib.nullcontext():
            res = run_episode(env, agent, seed=args.seed,
                              options={"omega_n": obj.omega_n, "alpha": obj.alpha, "mass": obj.mass},
                              on_probe=None if args.json else show)
        plot_fm = _estimate_forward(env, agent) if plot is not None else None  # the plot's curve at the estimate
    except KeyboardInterrupt:  # the probes so far were shown as they finished; with --json, print them now
        done = env.unwrapped.table()
        if args.json:
            print(json.dumps({"physics": args.physics, "object": obj.name, "interrupted": True,
                              "probes": done.to_rows()}), flush=True)
        print(f"plate-env identify: interrupted after {len(done)} probes", file=sys.stderr)
        return 130
    finally:
        env.close()
    est = res.estimate
    if args.json:
        print(json.dumps({"physics": args.physics, "object": obj.name, **res.to_dict()}), flush=True)
    else:
        _print_identify(res)
    if plot is not None:
        from plate_env.plotting import plot_fit

        plot_fit(res.probes, est, str(plot), plot_fm, omega_n_true=obj.omega_n)  # the truth printed above
        _say_plot(args, plot)
    return 0 if est.ok else 1


def _estimate_forward(env, agent):
    """The forward model an episode's estimate was computed with (its estimator's,
    :func:`plate_env.env.episode.estimator_of`), or None (the Lorentz method, a lab calibration, a physics without
    one)."""
    from plate_env.env.episode import estimator_of

    forward_model = getattr(estimator_of(env, agent), "forward_model", None)
    try:
        return None if forward_model is None else forward_model()
    except ValueError:
        return None


def _intervals(est) -> str:
    """The 68 % and 95 % intervals of omega_n, rad/s and in units of pi."""
    (a, b), (c, d) = est.omega_n_ci68, est.omega_n_ci95
    return (f"              68 % interval {a:.2f}-{b:.2f} rad/s ({a / math.pi:.2f}-{b / math.pi:.2f} pi), "
            f"95 % interval {c:.2f}-{d:.2f} rad/s ({c / math.pi:.2f}-{d / math.pi:.2f} pi)")


def _print_identify(res) -> None:
    est = res.estimate
    if est.ok:
        print(f"omega_n_hat = {est.omega_n:.2f} +- {est.omega_n_stderr:.2f} rad/s ({format_omega_pi(est.omega_n)}) "
              f"by {est.method}")
        print(_intervals(est))
        print(f"true        = {res.omega_n_true:.2f} rad/s ({format_omega_pi(res.omega_n_true)});  "
              f"error {100 * res.relative_error:.1f} %")
        if est.alpha is not None:
            print(f"alpha_hat   = {math.degrees(est.alpha):.1f} +- {math.degrees(est.alpha_stderr):.1f} deg "
                  f"(true {math.degrees(res.alpha_true):.1f} deg)")
    else:
        print(f"no estimate: {est.reason}")
    print(f"{res.n_probes} probes, {res.sim_s:.1f} s simulated, {res.wall_s:.1f} s wall", flush=True)


def _add_cache(sub) -> None:
    c = sub.add_parser("cache", help="show or clear the disk cache of derived arrays (docs/speed.md)")
    c.add_argument("action", choices=("info", "clear"), help="info: where it is, its entries and their size; "
                   "clear: delete its entries (each is computed again when next needed)")


def _megabytes(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def _cmd_cache(args: argparse.Namespace) -> int:
    from plate_env.core.cache import cache_dir, cache_entries, clear_cache

    root = cache_dir()
    if root is None:
        print("cache: off (PLATE_ENV_CACHE_DIR=off): nothing is kept on disk")
        return 0
    if args.action == "clear":
        gone = clear_cache(root)
        print(f"cache {root}: deleted {len(gone)} entries, {_megabytes(sum(e.size_bytes for e in gone))}")
        return 0
    entries = cache_entries(root)
    print(f"cache {root}: {len(entries)} entries, {_megabytes(sum(e.size_bytes for e in entries))} "
          f"(no size limit: `plate-env cache clear` deletes them)")
    for kind in sorted({e.kind for e in entries}):
        of = [e for e in entries if e.kind == kind]
        print(f"  {kind}: {len(of)} entries, {_megabytes(sum(e.size_bytes for e in of))}")
    return 0


def _cmd_build(args: argparse.Namespace) -> int:
    """``plate-env build``: the builders of plate_env.build; ``policy`` trains with the agents' package, which only
    the command line imports (the seam to the agents)."""
    if args.artifact != "policy":
        return run_build(args, args.argv[1:])
    from plate_env.build.provenance import build_record, record_in_manifest
    from plate_env.core.files import check_output
    from plate_env_agents.train import train_policy

    for path in (Path(args.out), Path(args.out).with_suffix(".npz"), Path(args.out).with_suffix(".json")):
        check_output(path, "--out")  # before the training (an hour at the default steps), not at its save
    record = build_record(args.argv[1:])
    meta = train_policy(args.out, record, hyperparams=args.hyperparams, env_id=args.env_id,
                        seed=args.seed, timesteps=args.timesteps, eval_freq=args.eval_freq,
                        eval_episodes=args.eval_episodes, eval_seed=args.eval_seed, threads=args.threads)
    for path in (Path(args.out), Path(args.out).with_suffix(".npz"), Path(args.out).with_suffix(".json")):
        record_in_manifest(path, record)  # a shipped policy's files get their manifest entries
    out, ev = Path(args.out), meta["eval"]
    kept = (f"best eval reward {ev['best_reward']:.4f} at {ev['best_at_timesteps']} steps" if ev["curve"] else
            "no evaluation ran: the last model")
    print(f"trained {meta['timesteps']} steps in {meta['train_wall_s']:.0f} s (seed {meta['seed']}); {kept} -> {out}, "
          f"{out.with_suffix('.npz')}, {out.with_suffix('.json')}")
    return 0


COMMANDS = {"probe": _cmd_probe, "sweep": _cmd_sweep, "fit": _cmd_fit, "identify": _cmd_identify,
            "bench": _cmd_bench, "calibrate": _cmd_calibrate, "cache": _cmd_cache,
            "build": lambda args: _cmd_build(args)}


#: A command-line token that is a negative value, not an option: "-10pi", "-1e-3", "-inf", "-.5".
_NEGATIVE = re.compile(r"^-(\d|\.\d|inf|nan|pi|π)", re.IGNORECASE)


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--omega-n -10pi`` -> ``--omega-n=-10pi``: argparse takes a token starting with "-" for an option unless it
    looks like a plain negative number, and would answer "expected one argument" instead of checking the value."""
    out: list[str] = []
    for token in argv:
        if out and _NEGATIVE.match(token) and out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def _warn_one_line(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"plate-env: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command. Exit codes: 0 done, 1 no estimate, 2 bad input (one line naming it), 3 an internal error
    (one line; ``PLATE_ENV_TRACEBACK=1`` shows the traceback), 130 interrupted (finished probes are printed)."""
    parser = build_parser()
    raw = _join_negative_values(list(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(raw)
    args.argv = raw
    with warnings.catch_warnings():
        warnings.showwarning = _warn_one_line
        try:
            return COMMANDS[args.command](args)
        except (CliError, ValueError, OSError) as exc:
            print(f"plate-env {args.command}: error: {exc}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"plate-env {args.command}: interrupted", file=sys.stderr)
            return 130
        except Exception as exc:  # noqa: BLE001 - never a traceback for a user; a bug still says what it was
            if os.environ.get("PLATE_ENV_TRACEBACK"):
                raise
            print(f"plate-env {args.command}: internal error: {type(exc).__name__}: {exc} (a bug: please report it; "
                  f"PLATE_ENV_TRACEBACK=1 shows where)", file=sys.stderr)
            return 3


if __name__ == "__main__":
    raise SystemExit(main())
