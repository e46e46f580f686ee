"""Layer 6, the benchmark: named versioned suites (:mod:`~plate_env.bench.suites`), the runner and its records
(:mod:`~plate_env.bench.runner`: :func:`evaluate`), what names a record (:mod:`~plate_env.bench.fingerprint`), a
run's scores and comparisons (:mod:`~plate_env.bench.summary`, on the statistics of :mod:`~plate_env.bench.scoring`),
the leaderboard's markdown (:mod:`~plate_env.bench.report`) and report summaries (:mod:`~plate_env.bench.reporting`).

``from plate_env.bench import evaluate`` (``plate_env.bench.runner``, the old path, still imports with a
DeprecationWarning)."""

from plate_env.bench.fingerprint import code_fingerprint, outcome_modules
from plate_env.bench.report import AgentSummary, leaderboard_markdown, matrix_markdown, rank
from plate_env.bench.runner import BenchInterrupted, Episode, evaluate, play
from plate_env.bench.summary import AgentRun, board, board_to_dict, check_budgets, compare, summarize

__all__ = ["AgentRun", "AgentSummary", "BenchInterrupted", "Episode", "board", "board_to_dict", "check_budgets",
           "code_fingerprint", "compare", "evaluate", "leaderboard_markdown", "matrix_markdown", "outcome_modules",
           "play", "rank", "summarize"]
