"""Layer 6, the benchmark: named versioned suites (:mod:`~plate_env.bench.suites`), the runner and its records
(:mod:`~plate_env.bench.runner`: :func:`evaluate`, :func:`compare`), scores with bootstrap intervals
(:mod:`~plate_env.bench.scoring`) and report summaries (:mod:`~plate_env.bench.reporting`).

``from plate_env.bench import evaluate`` (``plate_env.benchmark``, the old path, still imports with a
DeprecationWarning)."""

from plate_env.bench.runner import (
    AgentRun,
    AgentSummary,
    BenchInterrupted,
    Episode,
    board,
    board_to_dict,
    compare,
    evaluate,
    leaderboard_markdown,
    summarize,
)

__all__ = ["AgentRun", "AgentSummary", "BenchInterrupted", "Episode", "board", "board_to_dict", "compare", "evaluate",
           "leaderboard_markdown", "summarize"]
