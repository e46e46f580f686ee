"""The benchmark: an agent on a suite's episodes, scored against simulated probing seconds, with bootstrap intervals.

    from plate_env.bench import evaluate
    run = evaluate(agent, "tilelink-v0")          # an agent following plate_env.env.protocol, or a factory of one
    print(run.summary().to_markdown())

Episodes. Every object of the suite (:mod:`plate_env.bench.suites`) is one episode: the env is reset with the object and
its seed, the agent's generator is seeded with the same seed, and the agent probes until it stops, the env's probe
budget ends, or the probes have taken the suite's largest budget in simulated seconds (the agent's context names
that budget; the env's observation is the one the env gives without a time budget, as policies are trained).

Budgets from one run. After every probe the estimate of the probes so far is computed with the agent's method.
The estimate at a budget of B simulated seconds is that of the longest prefix of the probes whose seconds add up to
at most B (none: no estimate). An agent that stopped before B is scored on all its probes, its final estimate. So
every budget is read from one episode run at the largest budget; an agent that would spend a smaller budget
differently if it were told so in advance is scored as an anytime agent.

Metrics (per budget, over the suite's objects; :mod:`~plate_env.bench.scoring`): median and 90th-percentile relative
error of omega_n_hat (no estimate = infinite error), no-estimate rate, 68 % and 95 % interval coverage, median 95 %
width, each with its 95 % percentile-bootstrap interval over objects; mean probes and median probing seconds used.
The error curve: median (and p90) error against the budget on a grid of :data:`CURVE_STEP_S` from 0 to the
largest budget, with errors capped at 100 % (no estimate counts as 100 %), and its area (the mean of the capped
median error over the budgets, a number in [0, 1]) with its bootstrap interval. Wall seconds per decision: the
mean time of the agent's ``next_probe`` calls in an episode, median over episodes (wall time: depends on the
machine and its load). Paired comparisons of two agents (:func:`compare`): the median of the per-object
differences of capped errors on the same episodes, with its bootstrap interval.

Records and resumption. Each finished episode is a JSON line (probes, the estimate after each probe, decision
times); with ``cache`` they are appended as they finish and a rerun skips the episodes already there. A record's
key names the suite's content hash, the agent (class, options, source file, model file) and the code that decides
an episode's outcome (the package's physics, env, identification and data files), so a record of other code is
not reused. Determinism: the same records give the same numbers (bootstrap generators seeded); an episode's record
depends only on the suite, the episode and the agent, not on the executor or on the episodes before it (wall
times aside) -- as far as the agent itself keeps no state across episodes beyond ``reset``.
"""

from __future__ import annotations

import json
import math
import pickle
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from plate_env.bench.fingerprint import agent_fingerprint, run_key
from plate_env.bench.suites import Suite, SuiteObject, load_suite
from plate_env.bench.summary import AgentRun, check_budgets
from plate_env.env.protocol import ProbingAgent, check_agent
from plate_env.identify.estimate import Estimate


# --------------------------------------------------------------------------------------------- episodes
@dataclass(frozen=True)
class Episode:
    """One finished episode: the truth, each probe's simulated seconds, the estimate after each probe."""

    index: int
    seed: int
    omega_n_true: float
    probe_sim_s: tuple[float, ...]
    prefix: tuple[Estimate, ...] = field(repr=False)
    decision_wall_s: tuple[float, ...]
    wall_s: float
    #: each probe as (f_p_hz, a_p_deg, omega_b_deg_s, stderr_deg_s, unstable)
    probes: tuple[tuple[float, float, float, float, bool], ...] = field(default=(), repr=False)

    def n_at(self, budget_s: float) -> int:
        """Probes finished within ``budget_s`` simulated seconds."""
        return int(np.searchsorted(np.cumsum(self.probe_sim_s), budget_s * (1 + 1e-12), side="right"))

    def estimate_at(self, budget_s: float) -> Estimate:
        """The estimate from the probes finished within ``budget_s`` (none: no estimate)."""
        k = self.n_at(budget_s)
        return self.prefix[k - 1] if k else Estimate(ok=False, method="none", reason="no probe within the budget")

    def sim_at(self, budget_s: float) -> float:
        return float(np.sum(self.probe_sim_s[: self.n_at(budget_s)]))

    @property
    def seconds_per_decision(self) -> float:
        return float(np.mean(self.decision_wall_s)) if self.decision_wall_s else 0.0

    def to_record(self, key: str) -> dict[str, Any]:
        return {"key": key, "index": self.index, "seed": self.seed, "omega_n_true": self.omega_n_true,
                "probe_sim_s": list(self.probe_sim_s), "prefix": [_est_record(e) for e in self.prefix],
                "decision_wall_s": list(self.decision_wall_s), "wall_s": self.wall_s,
                "probes": [list(p) for p in self.probes]}

    @classmethod
    def from_record(cls, d: dict[str, Any]) -> Episode:
        return cls(index=int(d["index"]), seed=int(d["seed"]), omega_n_true=float(d["omega_n_true"]),
                   probe_sim_s=tuple(d["probe_sim_s"]), prefix=tuple(_est_from(e) for e in d["prefix"]),
                   decision_wall_s=tuple(d["decision_wall_s"]), wall_s=float(d["wall_s"]),
                   probes=tuple(tuple(p) for p in d["probes"]))


def _est_record(e: Estimate) -> dict[str, Any]:
    return {"ok": e.ok, "method": e.method, "omega_n": e.omega_n, "ci68": list(e.omega_n_ci68),
            "ci95": list(e.omega_n_ci95), "bound": list(e.bound) if e.bound else None,
            "reason": (e.reason or "")[:300] or None}


def _est_from(d: dict[str, Any]) -> Estimate:
    ci68 = tuple(d["ci68"])
    return Estimate(ok=bool(d["ok"]), method=d["method"], reason=d["reason"], omega_n=float(d["omega_n"]),
                    omega_n_stderr=(ci68[1] - ci68[0]) / 2, omega_n_ci68=ci68, omega_n_ci95=tuple(d["ci95"]),
                    bound=tuple(d["bound"]) if d["bound"] else None)


def play(env: Any, agent: ProbingAgent, obj: SuiteObject, index: int, max_budget_s: float) -> Episode:
    """One episode of ``agent`` on ``env`` hiding suite object ``obj``: the probes until it stops or the budget
    ends, and the agent's estimate after every probe."""
    from plate_env.env.episode import run_episode

    res = run_episode(env, agent, seed=obj.seed, options=obj.reset_options(), max_sim_s=max_budget_s, prefix=True)
    t = res.probes
    prefix = res.prefix
    probes = tuple((float(f), float(a), float(w), float(s), bool(u)) for f, a, w, s, u in
                   zip(t.f_p_hz, t.a_p_deg, t.omega_b_deg_s, t.stderr_deg_s, t.unstable, strict=True))
    return Episode(index=index, seed=obj.seed, omega_n_true=obj.omega_n, probe_sim_s=res.probe_sim_s, prefix=prefix,
                   decision_wall_s=res.decision_wall_s, wall_s=res.wall_s, probes=probes)


# --------------------------------------------------------------------------------------------- running
class _Same:
    """A factory returning one agent instance (in this process; a pickled copy in a worker)."""

    def __init__(self, agent: ProbingAgent) -> None:
        self.agent = agent

    def __call__(self) -> ProbingAgent:
        return self.agent


#: This process's envs, by suite content hash, and agents, by their pickled factory (a worker keeps both between
#: chunks: loading a policy through torch takes seconds; an agent starts every episode afresh by ``reset``).
_ENVS: dict[str, Any] = {}
_AGENTS: dict[bytes, ProbingAgent] = {}


def _agent_of(factory: Callable[[], ProbingAgent]) -> ProbingAgent:
    if isinstance(factory, _Same):
        return factory()
    try:
        key = pickle.dumps(factory)
    except Exception:  # noqa: BLE001 - an unpicklable factory only runs in this process: no reuse across chunks
        return factory()
    if key not in _AGENTS:
        _AGENTS.clear()  # one agent at a time
        _AGENTS[key] = factory()
    return _AGENTS[key]


#: One episode to play: (agent factory, suite, object index, largest budget in simulated s).
EpisodeTask = tuple[Callable[[], ProbingAgent], Suite, int, float]


def run_episode_chunk(items: Sequence[EpisodeTask]) -> list[Episode]:
    """Executor ``fn``: play episodes ``(agent factory, suite, index, max budget)`` in this process (the env of a
    suite and the agent of a factory are built once per process)."""
    out = []
    for factory, suite, index, budget in items:
        env = _ENVS.get(suite.sha256)
        if env is None:
            env = _ENVS[suite.sha256] = suite.make_env()
        out.append(play(env, _agent_of(factory), suite.objects[index], index, budget))
    return out


class BenchInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`evaluate`: ``finished`` episodes were kept (in the cache, when one was given)."""

    def __init__(self, finished: int, cache: Path | None) -> None:
        super().__init__()
        self.finished = finished
        self.cache = cache


def _numbers_problem(name: str, v: object, lo: float = -math.inf, length: int | None = None) -> str | None:
    """Why ``v`` is not a list (of ``length`` items, when given) of finite numbers >= ``lo``, else None."""
    from plate_env.run.sweeps import number_problem

    if not isinstance(v, list) or (length is not None and len(v) != length):
        return f"{name} = {v!r} is not a list of {length or 'some'} numbers"
    return next((p for i, x in enumerate(v) if (p := number_problem(f"{name}[{i}]", x, lo))), None)


def episode_record_problem(d: dict[str, Any]) -> str | None:
    """Why a bench-cache record cannot be loaded (a field missing, of the wrong type, non-finite or out of range;
    a probe count that differs between its lists), else None."""
    from plate_env.run.sweeps import number_problem

    problems = [number_problem("index", d.get("index"), 0, integral=True),
                number_problem("seed", d.get("seed"), 0, integral=True),
                number_problem("omega_n_true", d.get("omega_n_true"), 1e-300),
                _numbers_problem("probe_sim_s", d.get("probe_sim_s"), 0.0),
                _numbers_problem("decision_wall_s", d.get("decision_wall_s"), 0.0),
                number_problem("wall_s", d.get("wall_s"), 0.0)]
    if (p := next((p for p in problems if p), None)):
        return p
    n = len(d["probe_sim_s"])
    prefix, probes = d.get("prefix"), d.get("probes")
    if not isinstance(prefix, list) or len(prefix) != n:
        return f"prefix is not a list of {n} estimates (one per probe)"
    if not isinstance(probes, list) or len(probes) != n:
        return f"probes is not a list of {n} probes"
    for i, e in enumerate(prefix):
        if not isinstance(e, dict) or not isinstance(e.get("ok"), bool) or not isinstance(e.get("method"), str):
            return f"prefix[{i}] = {e!r} is not an estimate (ok, method, omega_n, ci68, ci95, bound, reason)"
        p = (number_problem(f"prefix[{i}].omega_n", e.get("omega_n"))
             or _numbers_problem(f"prefix[{i}].ci68", e.get("ci68"), length=2)
             or _numbers_problem(f"prefix[{i}].ci95", e.get("ci95"), length=2))
        b = e.get("bound")
        if p is None and b is not None and not (isinstance(b, list) and len(b) == 2 and isinstance(b[0], str)
                                                 and number_problem("", b[1]) is None):
            p = f"prefix[{i}].bound = {b!r} is not [side, omega_n]"
        if p is None and not (e.get("reason") is None or isinstance(e.get("reason"), str)):
            p = f"prefix[{i}].reason = {e.get('reason')!r} is not a string or null"
        if p:
            return p
    for i, q in enumerate(probes):
        p = (None if isinstance(q, list) and len(q) == 5 and isinstance(q[4], bool)
             else f"probes[{i}] = {q!r} is not [f_p_hz, a_p_deg, omega_b_deg_s, stderr_deg_s, unstable]")
        p = p or (number_problem(f"probes[{i}].f_p_hz", q[0], 1e-300) or number_problem(f"probes[{i}].a_p_deg", q[1])
                  or number_problem(f"probes[{i}].omega_b_deg_s", q[2])
                  or number_problem(f"probes[{i}].stderr_deg_s", q[3], 0.0))
        if p:
            return p
    return None


def _load_records(path: Path, key: str) -> dict[int, Episode]:
    """The cache's episodes of run ``key`` by index. A record with a bad field is skipped with a warning naming the
    file, line and field (its episode runs again), never loaded."""
    import warnings

    from plate_env.run.sweeps import numbered_records

    out: dict[int, Episode] = {}
    for lineno, d in numbered_records(path):
        if d.get("key") != key:
            continue
        problem = episode_record_problem(d)
        if problem:
            warnings.warn(f"{path}: line {lineno}: {problem}; the record is skipped (its episode runs again)",
                          stacklevel=2)
            continue
        out[int(d["index"])] = Episode.from_record(d)
    return out


def evaluate(agent: ProbingAgent | Callable[[], ProbingAgent], suite: Suite | str, *, label: str | None = None,
             budgets_s: Sequence[float] | None = None, executor: str | None = None, cache: str | Path | None = None,
             limit: int | None = None, progress: bool = False, chunk: int = 2) -> AgentRun:
    """Play ``agent`` on every episode of ``suite`` and return the :class:`AgentRun` (see the module docstring).

    ``agent``: an agent (:mod:`plate_env.env.protocol`) or a zero-argument factory of one (a picklable one, e.g.
    ``functools.partial(plate_env_agents.load_agent, "bayes")``, for process or Ray executors). ``budgets_s``:
    the budgets to score (default the suite's; each at most its largest; episodes always run to the largest).
    ``executor``: where episodes run (:func:`plate_env.run.executor.make_executor` names; default in-process, a process
    pool for PyBullet), ``chunk`` episodes per task. ``cache``: a JSON-lines file of finished episodes (appended as
    they finish; a rerun resumes). ``limit``: only the first ``limit`` objects (quick looks; not the suite's result).
    Ctrl-C raises :class:`BenchInterrupted` after the finished episodes are written.
    """
    from plate_env.run.executor import BackendSpec, check_executor_name, make_executor
    from plate_env.run.sweeps import open_for_append

    suite = load_suite(suite) if isinstance(suite, str) else suite
    budgets = check_budgets(suite, budgets_s)
    n = len(suite.objects) if limit is None else min(int(limit), len(suite.objects))
    if n < 1:
        raise ValueError(f"limit = {limit!r}: at least one object")
    factory: Callable[[], ProbingAgent] = (agent if (callable(agent) and not hasattr(agent, "next_probe"))
                                           else _Same(cast(ProbingAgent, agent)))
    probe_agent = check_agent(factory(), where=label or "agent")
    label = label or probe_agent.name
    key = run_key(suite, agent_fingerprint(probe_agent), suite.max_budget_s)
    check_executor_name(executor)
    path = Path(cache) if cache else None
    done = _load_records(path, key) if path else {}
    todo = [i for i in range(n) if i not in done]
    if todo:
        backend = BackendSpec.of(suite.physics, **dict(suite.env_kwargs.get("physics_options") or {}))
        ex = make_executor(executor, backend)
        if ex.name != "inprocess":
            try:
                pickle.dumps(factory)
            except Exception as exc:  # noqa: BLE001 - any pickling failure means the same thing here
                ex.close()
                raise ValueError(f"agent {label!r} cannot be sent to {ex.name} workers ({exc}); pass a picklable "
                                 "factory (e.g. functools.partial(load_agent, spec)) or run in-process") from None
        chunks = [[(factory, suite, i, suite.max_budget_s) for i in todo[j:j + chunk]]
                  for j in range(0, len(todo), chunk)]
        bar = None
        if progress:
            from plate_env.core.progress import progress_bar

            bar = progress_bar(n, f"{label} on {suite.name}", "episode", initial=n - len(todo))
        fh = open_for_append(path) if path else None
        try:
            for _, episodes in ex.map(run_episode_chunk, chunks):
                for ep in episodes:
                    done[ep.index] = ep
                    if fh is not None:
                        fh.write((json.dumps(ep.to_record(key)) + "\n").encode())
                if fh is not None:
                    fh.flush()
                if bar is not None:
                    bar.update(len(episodes))
        except KeyboardInterrupt:
            raise BenchInterrupted(sum(i in done for i in range(n)), path) from None
        finally:
            ex.close()
            if fh is not None:
                fh.close()
            if bar is not None:
                bar.close()
    return AgentRun(label=label, suite=suite, budgets_s=budgets, episodes=tuple(done[i] for i in range(n)), key=key,
                    limit=None if n == len(suite.objects) else n)


__all__ = ["BenchInterrupted", "Episode", "evaluate", "play", "run_episode_chunk"]
