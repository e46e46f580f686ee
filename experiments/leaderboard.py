"""The leaderboard of the shipped agents on a suite: one command, resumable.

    python experiments/leaderboard.py [--suite tilelink-v0] [--agents SPEC ...] [--executor pool:2] [--readme]

Runs every agent on every episode of the suite through plate_env.benchmark (finished episodes are kept in
experiments/cache/bench_<suite>.jsonl, so a killed run resumes and a rerun only plays what changed: a record names
the suite, the agent and the code that decided its outcome), then writes experiments/results/leaderboard_<suite>.md
(the ranked table, every metric per budget with 95 % bootstrap intervals over objects, paired differences against
the leader), .json and .png. ``--readme`` also re-renders the README's and docs' tables from the results
(experiments/readme_tables.py). Agents: the shipped ones (grid: the paper's sweep and Lorentzian fit; the same
sweep read by the atlas posterior; coarse_to_fine; bayes; ppo), the PPO trained from the README's snippet if its
model exists, and the README's example third-party agent, each by the spec ``plate-env bench --agent`` takes.
"""

from __future__ import annotations

import argparse
import functools
import json
import platform
import time
from pathlib import Path

from plate_env import benchmark
from plate_env.executor import add_executor_argument
from plate_env.suites import load_suite
from plate_env_agents import load_agent

RESULTS = Path("experiments/results")
#: The PPO trained from the README's snippet (experiments/train_readme_ppo.py writes it).
README_PPO = "experiments/results/models/readme_ppo.zip"
EXAMPLE_AGENT = "examples/sweep_agent.py:SweepAgent"
SHIPPED = ("grid", "grid:method=atlas", "coarse_to_fine", "bayes", "ppo")


def default_agents() -> list[str]:
    out = list(SHIPPED)
    if Path(README_PPO).exists():
        out.append(f"sb3:{README_PPO}")
    return out + [EXAMPLE_AGENT]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default="tilelink-v0")
    ap.add_argument("--agents", nargs="+", default=None, help="agent specs (default: the shipped agents and more)")
    ap.add_argument("--cache", default=None, help="default experiments/cache/bench_<suite>.jsonl")
    ap.add_argument("--out", default=None, help="results stem (default experiments/results/leaderboard_<suite>)")
    ap.add_argument("--chunk", type=int, default=2)
    ap.add_argument("--readme", action="store_true", help="re-render the README's and docs' tables")
    add_executor_argument(ap)
    args = ap.parse_args()
    suite = load_suite(args.suite)
    specs = args.agents or default_agents()
    for spec in specs:
        load_agent(spec)  # every spec checked before any episode runs
    cache = args.cache or f"experiments/cache/bench_{suite.name}.jsonl"
    runs, walls = [], {}
    for spec in specs:
        t0 = time.perf_counter()
        runs.append(benchmark.evaluate(functools.partial(load_agent, spec), suite, label=spec,
                                       executor=args.executor, cache=cache, chunk=args.chunk, progress=True))
        walls[spec] = round(time.perf_counter() - t0, 1)
        print(f"{spec}: {len(runs[-1].episodes)} episodes ({walls[spec]} s this run)", flush=True)
    b = benchmark.board(runs)
    note = (f"Regenerate: `python experiments/leaderboard.py --suite {suite.name}`. Wall seconds per decision were "
            f"measured on a shared 2-core machine (load {_load()}), noisy.")
    table = benchmark.leaderboard_markdown(b["summaries"], b["paired"], b["leader"], note=note)
    stem = Path(args.out or RESULTS / f"leaderboard_{suite.name}")
    stem.parent.mkdir(parents=True, exist_ok=True)
    stem.with_suffix(".md").write_text(f"# Leaderboard: {suite.name}\n\n{suite.description}\n\n{table}")
    stem.with_suffix(".json").write_text(json.dumps({"suite": suite.name, "suite_sha256": suite.sha256,
                                                     "python": platform.python_version(),
                                                     **benchmark.board_to_dict(b)}, indent=1) + "\n")
    print(table, flush=True)
    benchmark.plot_curves(b["summaries"], str(stem.with_suffix(".png")))
    if args.readme:
        import readme_tables  # experiments/ is on sys.path when this script runs

        readme_tables.main([])


def _load() -> str:
    try:
        return Path("/proc/loadavg").read_text().split()[0]
    except OSError:
        return "?"


if __name__ == "__main__":
    main()
