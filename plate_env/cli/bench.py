"""``plate-env bench``: score agents on versioned suites."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from plate_env.cli.options import CliError, number_arg, output_path, plot_path, say_plot
from plate_env.core import checks
from plate_env.core.streams import stdout_to_stderr
from plate_env.run.executor import BackendSpec, add_executor_argument

if TYPE_CHECKING:
    from plate_env.cli.options import Subparsers

#: Where ``bench`` keeps finished episodes unless told otherwise (a rerun resumes from there).
BENCH_CACHE_DIR = ".plate_env_bench"


def add_parser(sub: Subparsers) -> None:
    b = sub.add_parser("bench", help="score agents on a versioned suite: error against probing seconds, intervals")
    b.add_argument("--suite", nargs="+", default=["atlas-v0"], help="suite name (atlas-v0, tilelink-v0, "
                   "pybullet-v0, faithful-v0, misspec_pointmass-v0, misspec_faithful-v0, misspec_pybullet-v0) or a "
                   "suite .json file; several: every agent on every suite, and a table of agents against suites")
    b.add_argument("--agent", action="extend", nargs="+", required=True,
                   help="one or more agents: bayes, grid, coarse_to_fine, ppo (options: grid:n=30,method=atlas), "
                        "path/to/file.py:MyAgent, sb3:model.zip (sb3:td3:model.zip: ppo, a2c, sac, td3, ddpg)")
    b.add_argument("--budgets", default=None, help="probing budgets to score, simulated s, comma list (default: the "
                   "suite's; each at most its largest)")
    b.add_argument("--limit", type=number_arg(checks.integer, 1, 100_000), default=None,
                   help="only the first N objects (a quick look, not the suite's result; default: all)")
    b.add_argument("--cache", default=None, help=f"JSON-lines file of finished episodes, a rerun resumes (default "
                   f"{BENCH_CACHE_DIR}/<suite>.jsonl)")
    b.add_argument("--no-cache", action="store_true", help="keep no episodes on disk")
    b.add_argument("--chunk", type=number_arg(checks.integer, 1, 1000), default=2, help="episodes per task")
    b.add_argument("--markdown", default=None, help="also write the leaderboard, under a title and the suite's "
                   "description, to this markdown file")
    b.add_argument("--plot", default=None, help="write the error curves (after the results are printed)")
    b.add_argument("--no-progress", action="store_true", help="no progress bar")
    b.add_argument("--json", action="store_true", help="print one JSON document")
    add_executor_argument(b)


def _nulled(obj: Any, path: str, nulled: list[str]) -> Any:
    if isinstance(obj, float) and not math.isfinite(obj):
        nulled.append(path)
        return None
    if isinstance(obj, dict):
        return {k: _nulled(v, f"{path}.{k}" if path else str(k), nulled) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_nulled(v, f"{path}[{i}]", nulled) for i, v in enumerate(obj)]
    return obj


def strict_json(doc: dict[str, Any]) -> str:
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


def run(args: argparse.Namespace) -> int:
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
        say_plot(args, plot)
    return 0
