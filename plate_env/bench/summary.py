"""An agent's run on a suite and its scores: per budget, the error curve and its area, paired comparisons, the
board of several agents (see :mod:`plate_env.bench.runner` for what the numbers mean)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from plate_env.bench.report import AgentSummary, BudgetScores, rank
from plate_env.bench.scoring import Stat, bootstrap, paired_difference, score
from plate_env.bench.suites import Suite
from plate_env.identify.estimate import Estimate

#: Grid step of the error curve, simulated seconds.
CURVE_STEP_S = 0.25
#: Errors are capped here on the curve and in paired differences (no estimate counts as this).
ERROR_CAP = 1.0
#: Bootstrap resamples.
N_BOOT = 2000


class ScoredEpisode(Protocol):
    """What the scores read of an episode (:class:`plate_env.bench.runner.Episode`)."""

    @property
    def omega_n_true(self) -> float: ...

    @property
    def seconds_per_decision(self) -> float: ...

    def n_at(self, budget_s: float) -> int: ...

    def estimate_at(self, budget_s: float) -> Estimate: ...

    def sim_at(self, budget_s: float) -> float: ...


@dataclass(frozen=True)
class AgentRun:
    """An agent's episodes on a suite (``episodes`` in suite order; ``limit`` set when only the first objects ran)."""

    label: str
    suite: Suite = field(repr=False)
    budgets_s: tuple[float, ...]
    episodes: tuple[ScoredEpisode, ...] = field(repr=False)
    key: str = ""
    limit: int | None = None

    def summary(self, budgets_s: Sequence[float] | None = None, seed: int = 0, n_boot: int = N_BOOT) -> AgentSummary:
        return summarize(self, budgets_s, seed=seed, n_boot=n_boot)


def check_budgets(suite: Suite, budgets_s) -> tuple[float, ...]:
    if budgets_s is None:
        return suite.budgets_s
    out = tuple(sorted({float(b) for b in budgets_s}))
    if not out or not all(math.isfinite(b) and 0 < b <= suite.max_budget_s for b in out):
        raise ValueError(f"budgets {list(budgets_s)!r}: simulated seconds in (0, {suite.max_budget_s:g}] (suite "
                         f"{suite.name}'s largest budget; a longer one is another suite version)")
    return out


def capped_errors(run: AgentRun, budget_s: float) -> np.ndarray:
    """Per-object relative errors at ``budget_s``, capped at :data:`ERROR_CAP` (no estimate counts as the cap)."""
    return np.array([min(ep.estimate_at(budget_s).relative_error(ep.omega_n_true), ERROR_CAP) for ep in run.episodes])


def curve_grid(run: AgentRun) -> np.ndarray:
    return np.round(np.arange(0.0, run.suite.max_budget_s + 1e-9, CURVE_STEP_S), 9)


def _area(x: np.ndarray) -> np.ndarray:
    """Mean over the budget grid (last axis) of the median over objects (axis -2), trapezoid rule."""
    med = np.median(x, axis=-2)
    return (0.5 * (med[..., 1:] + med[..., :-1])).mean(axis=-1)


def summarize(run: AgentRun, budgets_s: Sequence[float] | None = None, seed: int = 0,
              n_boot: int = N_BOOT) -> AgentSummary:
    """Scores of ``run`` at each budget, its error curve and area, seconds per decision; every interval a
    percentile bootstrap over objects from ``numpy.random.default_rng(seed)`` (the same numbers every time)."""
    budgets = check_budgets(run.suite, budgets_s if budgets_s is not None else run.budgets_s)
    truth = [ep.omega_n_true for ep in run.episodes]
    rows = []
    for b in budgets:
        sc = score(truth, [ep.estimate_at(b) for ep in run.episodes], np.random.default_rng(seed), n_boot)
        rows.append(BudgetScores(b, sc, float(np.mean([ep.n_at(b) for ep in run.episodes])),
                                 float(np.median([ep.sim_at(b) for ep in run.episodes]))))
    grid = curve_grid(run)
    errs = np.stack([capped_errors(run, g) for g in grid], axis=1)  # (objects, grid)
    area = bootstrap(errs, _area, np.random.default_rng(seed), n_boot)
    p90 = np.percentile(errs, 90, axis=0)

    def area90(x: np.ndarray) -> np.ndarray:
        q = np.percentile(x, 90, axis=-2)
        return (0.5 * (q[..., 1:] + q[..., :-1])).mean(axis=-1)

    per_dec = bootstrap([ep.seconds_per_decision for ep in run.episodes], lambda x: np.median(x, axis=-1),
                        np.random.default_rng(seed), n_boot)
    return AgentSummary(label=run.label, suite=run.suite.name, suite_sha256=run.suite.sha256, n=len(run.episodes),
                        limit=run.limit, budgets=tuple(rows), area=area,
                        area_p90=bootstrap(errs, area90, np.random.default_rng(seed), n_boot),
                        seconds_per_decision=per_dec, curve_s=tuple(float(g) for g in grid),
                        curve_median=tuple(float(x) for x in np.median(errs, axis=0)),
                        curve_p90=tuple(float(x) for x in p90))


def compare(run_a: AgentRun, run_b: AgentRun, budget_s: float, seed: int = 0, n_boot: int = N_BOOT) -> Stat:
    """Median paired difference of capped errors, ``a - b``, over the same episodes at ``budget_s``, with its
    bootstrap interval (negative: ``a`` is the more accurate; an interval without 0: they differ on this suite)."""
    if run_a.suite.sha256 != run_b.suite.sha256 or len(run_a.episodes) != len(run_b.episodes):
        raise ValueError(f"{run_a.label} and {run_b.label} did not play the same episodes (suite "
                         f"{run_a.suite.name} x {len(run_a.episodes)} against {run_b.suite.name} x "
                         f"{len(run_b.episodes)})")
    return paired_difference(capped_errors(run_a, budget_s), capped_errors(run_b, budget_s),
                             np.random.default_rng(seed), n_boot)


def paired_table(runs: dict[str, AgentRun], leader: str, budgets: Sequence[float], seed: int = 0) -> dict:
    """``{label: {budget: Stat}}``: each agent's paired difference against ``leader`` at each budget."""
    return {label: {b: compare(run, runs[leader], b, seed) for b in budgets}
            for label, run in runs.items() if label != leader}


def board(runs: Sequence[AgentRun], budgets_s: Sequence[float] | None = None, seed: int = 0) -> dict:
    """Summaries, the leader and the paired differences of several agents' runs on one suite:
    ``{"summaries": [...], "leader": label, "paired": {...}}``."""
    if len({r.label for r in runs}) != len(runs):
        raise ValueError(f"agent labels must differ: {[r.label for r in runs]}")
    summaries = [r.summary(budgets_s, seed=seed) for r in runs]
    leader = rank(summaries)[0].label
    budgets = [b.budget_s for b in summaries[0].budgets]
    paired = paired_table({r.label: r for r in runs}, leader, budgets, seed) if len(runs) > 1 else {}
    return {"summaries": summaries, "leader": leader, "paired": paired}


def board_to_dict(b: dict) -> dict:
    return {"leader": b["leader"], "agents": [s.to_dict() for s in rank(b["summaries"])],
            "paired_against_leader": {label: {f"{k:g}": v.to_dict() for k, v in per.items()}
                                      for label, per in b["paired"].items()}}


__all__ = ["AgentRun", "ScoredEpisode", "board", "board_to_dict", "compare",
           "summarize"]
