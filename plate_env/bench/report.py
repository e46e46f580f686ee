"""An agent's scores on a suite (:class:`AgentSummary`, computed by :func:`plate_env.bench.summary.summarize`) and
the leaderboard as markdown: agents ranked by the area of their median-error curve, every metric per budget with
its bootstrap interval, the paired differences against the leader."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from plate_env.bench.scoring import Scores, Stat


@dataclass(frozen=True)
class BudgetScores:
    """An agent's scores at one budget: :class:`~plate_env.bench.scoring.Scores`, mean probes, median seconds used."""

    budget_s: float
    scores: Scores
    probes: float
    sim_s: float

    def to_dict(self) -> dict:
        return {"budget_s": self.budget_s, **self.scores.to_dict(), "probes_mean": self.probes,
                "sim_s_median": self.sim_s}


@dataclass(frozen=True)
class AgentSummary:
    """An agent's scores on a suite (see the module docstring)."""

    label: str
    suite: str
    suite_sha256: str
    n: int
    limit: int | None
    budgets: tuple[BudgetScores, ...]
    area: Stat
    area_p90: Stat
    seconds_per_decision: Stat
    curve_s: tuple[float, ...] = field(repr=False)
    curve_median: tuple[float, ...] = field(repr=False)
    curve_p90: tuple[float, ...] = field(repr=False)

    def at(self, budget_s: float) -> BudgetScores:
        for b in self.budgets:
            if math.isclose(b.budget_s, budget_s):
                return b
        raise KeyError(f"budget {budget_s:g} s was not scored ({[b.budget_s for b in self.budgets]})")

    def to_dict(self) -> dict:
        return {"label": self.label, "suite": self.suite, "suite_sha256": self.suite_sha256, "n": self.n,
                "limit": self.limit, "budgets": [b.to_dict() for b in self.budgets], "area": self.area.to_dict(),
                "area_p90": self.area_p90.to_dict(), "seconds_per_decision": self.seconds_per_decision.to_dict(),
                "curve": {"budget_s": list(self.curve_s), "median_error": list(self.curve_median),
                          "p90_error": list(self.curve_p90)}}

    def to_markdown(self) -> str:
        return leaderboard_markdown([self], {})


def _pct(s: Stat, digits: int = 1) -> str:
    if not math.isfinite(s.value):  # inf, or nan (a quantile between no-estimates): beyond every estimate
        return "none"
    hi = f"{100 * s.hi:.{digits}f}" if math.isfinite(s.hi) else "inf"
    return f"{100 * s.value:.{digits}f} [{100 * s.lo:.{digits}f}, {hi}]"


def rank(summaries: Sequence[AgentSummary]) -> list[AgentSummary]:
    """Best first: by the area of the median-error curve."""
    return sorted(summaries, key=lambda s: (s.area.value, s.label))


def leaderboard_markdown(summaries: Sequence[AgentSummary], paired: dict, leader: str | None = None,
                         note: str = "", detail: bool = True) -> str:
    """The leaderboard: ranked agents with their errors at each budget and intervals, then (``detail``) every metric
    per budget, then the paired differences against the leader."""
    ranked = rank(summaries)
    s0 = ranked[0]
    budgets = [b.budget_s for b in s0.budgets]
    top = budgets[-1]
    scope = f"first {s0.limit} of its objects" if s0.limit else f"{s0.n} objects"
    lines = [f"Suite `{s0.suite}` ({scope}; sha256 {s0.suite_sha256[:12]}). Errors in % with 95 % bootstrap "
             "intervals over objects; no estimate counts as an infinite error (as 100 % in the area). " + note, "",
             "| rank | agent | area: mean median error over 0-" + f"{top:g} s | "
             + " | ".join(f"median error @ {b:g} s" for b in budgets)
             + f" | p90 @ {top:g} s | no estimate @ {top:g} s | coverage 68 % / 95 % @ {top:g} s | probes @ {top:g} s"
             " | wall s per decision |",
             "|---|---|---|" + "---|" * len(budgets) + "---|---|---|---|---|"]
    for i, s in enumerate(ranked, 1):
        b = s.at(top)
        lines.append(f"| {i} | {s.label} | {_pct(s.area)} | "
                     + " | ".join(_pct(s.at(x).scores.median_error) for x in budgets)
                     + f" | {_pct(b.scores.p90_error)} | {_pct(b.scores.no_estimate)} | "
                     f"{_pct(b.scores.coverage68, 0)} / {_pct(b.scores.coverage95, 0)} | {b.probes:.1f} | "
                     f"{s.seconds_per_decision.value:.3g} [{s.seconds_per_decision.lo:.3g}, "
                     f"{s.seconds_per_decision.hi:.3g}] |")
    for x in budgets if detail else ():
        lines += ["", f"### Budget {x:g} simulated s", "",
                  "| agent | median error | p90 error | no estimate | coverage 68 % | coverage 95 % "
                  "| median 95 % width | probes (mean) | probing s (median) |", "|---|---|---|---|---|---|---|---|---|"]
        for s in ranked:
            b = s.at(x)
            sc = b.scores
            lines.append(f"| {s.label} | {_pct(sc.median_error)} | {_pct(sc.p90_error)} | {_pct(sc.no_estimate)} | "
                         f"{_pct(sc.coverage68, 0)} | {_pct(sc.coverage95, 0)} | {_pct(sc.width95)} | {b.probes:.1f}"
                         f" | {b.sim_s:.1f} |")
    if paired and leader:
        title = f"Paired differences against the leader, `{leader}` (same episodes)"
        lines += ["", f"### {title}" if detail else f"**{title}**", "",
                  "Median over objects of (agent's error - leader's error), errors capped at 100 %, in percentage "
                  "points with 95 % bootstrap intervals; an interval above 0: the leader is more accurate there.", "",
                  "| agent | " + " | ".join(f"@ {b:g} s" for b in budgets) + " |",
                  "|---|" + "---|" * len(budgets)]
        for s in ranked:
            if s.label in paired:
                lines.append(f"| {s.label} | " + " | ".join(_pct(paired[s.label][b]) for b in budgets) + " |")
    return "\n".join(lines) + "\n"


def matrix_markdown(columns: dict[str, Sequence[AgentSummary]], budget_s: float, note: str = "") -> str:
    """Agents (rows, in the order first given) against suites (columns, ``{suite name: its summaries}``): each cell
    the median error with its bootstrap interval, then p90 error, 95 % coverage and no-estimate share at
    ``budget_s``; "-" where an agent was not run on a suite. The misspecification track's table."""
    agents = list(dict.fromkeys(s.label for summaries in columns.values() for s in summaries))
    by = {(name, s.label): s for name, summaries in columns.items() for s in summaries}
    lines = [f"Each cell: median error [95 % CI] · p90 · 95 % coverage · no estimate, in %, at {budget_s:g} simulated "
             "s; intervals are bootstrap over objects; no estimate counts as an infinite error. " + note, "",
             "| agent | " + " | ".join(f"`{name}`" for name in columns) + " |", "|---|" + "---|" * len(columns)]
    for label in agents:
        cells = []
        for name in columns:
            s = by.get((name, label))
            if s is None:
                cells.append("-")
                continue
            sc = s.at(budget_s).scores
            cells.append(f"{_pct(sc.median_error)} · {_pct_value(sc.p90_error)} · {_pct_value(sc.coverage95, 0)} · "
                         f"{_pct_value(sc.no_estimate, 0)}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _pct_value(s: Stat, digits: int = 1) -> str:
    return f"{100 * s.value:.{digits}f}" if math.isfinite(s.value) else "none"


__all__ = ["AgentSummary", "BudgetScores", "leaderboard_markdown", "matrix_markdown", "rank"]
