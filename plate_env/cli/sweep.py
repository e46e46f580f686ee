"""``plate-env sweep``: a batched frequency sweep, resumable from a cache, on any executor."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

import numpy as np

from plate_env.cli.options import (
    MAX_SWEEP_PROBES,
    CliError,
    add_common,
    number_arg,
    object_spec,
    output_path,
    physics_options,
    plot_path,
    probe_spec,
    say_plot,
)
from plate_env.core import checks
from plate_env.core.objects import ObjectSpec
from plate_env.core.probe import MIN_PROBE_FREQ_HZ
from plate_env.core.setup import (
    FREQ_RANGE_HZ,
)
from plate_env.core.streams import stdout_to_stderr
from plate_env.core.units import format_omega_pi
from plate_env.physics.interface import refuse_early
from plate_env.run.executor import BackendSpec, add_executor_argument, make_executor

if TYPE_CHECKING:
    from plate_env.cli.options import Subparsers
    from plate_env.core.probe import ProbeResult


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


def add_parser(sub: Subparsers) -> None:
    """The ``sweep`` command on the CLI's subparsers ``sub``."""
    s = sub.add_parser("sweep", help="run a batched frequency sweep")
    add_common(s)
    s.add_argument("--freqs", default="10:40:1", help="start:stop:step or a comma list, Hz")
    s.add_argument("--plot", default=None, help="write a PNG of omega_B vs f_p (after the results are printed)")
    s.add_argument("--csv", default=None, help="also write the probes as a CSV that `plate-env fit` reads")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    s.add_argument("--cache", default=None, help="JSON-lines file: finished chunks are appended, a rerun resumes")
    s.add_argument("--chunk", type=number_arg(checks.integer, 1, MAX_SWEEP_PROBES), default=8,
                   help="probes per chunk (a unit of work and of persistence)")
    add_executor_argument(s)


def _print_sweep(args: argparse.Namespace, obj: ObjectSpec, results: list[ProbeResult], interrupted: bool) -> None:
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


def run(args: argparse.Namespace) -> int:
    from plate_env.run.sweeps import SweepInterrupted, run_cached

    obj = object_spec(args)
    freqs = parse_freqs(args.freqs)
    plot = plot_path(args.plot) if args.plot else None
    csv_out = output_path(args.csv, "--csv") if args.csv else None
    specs = [probe_spec(args, obj, f) for f in freqs]
    backend = BackendSpec.of(args.physics, **physics_options(args))
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
        say_plot(args, plot)
    return 0
