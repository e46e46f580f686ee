"""The benchmark: an agent on a suite's episodes, scored against simulated probing seconds, with bootstrap intervals.

    from plate_env.bench.runner import evaluate
    run = evaluate(agent, "tilelink-v0")          # an agent following plate_env.protocol, or a factory of one
    print(run.summary().to_markdown())

Episodes. Every object of the suite (:mod:`plate_env.suites`) is one episode: the env is reset with the object and
its seed, the agent's generator is seeded with the same seed, and the agent probes until it stops, the env's probe
budget ends, or the probes have taken the suite's largest budget in simulated seconds (the agent's context names
that budget; the env's observation is the one the env gives without a time budget, as policies are trained).

Budgets from one run. After every probe the estimate of the probes so far is computed with the agent's method.
The estimate at a budget of B simulated seconds is that of the longest prefix of the probes whose seconds add up to
at most B (none: no estimate). An agent that stopped before B is scored on all its probes, its final estimate. So
every budget is read from one episode run at the largest budget; an agent that would spend a smaller budget
differently if it were told so in advance is scored as an anytime agent.

Metrics (per budget, over the suite's objects; :mod:`plate_env.scoring`): median and 90th-percentile relative error
of omega_n_hat (no estimate = infinite error), no-estimate rate, 68 % and 95 % interval coverage, median 95 %
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

import functools
import hashlib
import inspect
import json
import math
import pickle
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from plate_env.bench.scoring import Scores, Stat, bootstrap, paired_difference, score
from plate_env.bench.suites import Suite, load_suite
from plate_env.env.protocol import check_agent
from plate_env.identify.estimate import Estimate

#: Version of the episode record (part of every record's key).
RECORD_FORMAT = 1
#: Grid step of the error curve, simulated seconds.
CURVE_STEP_S = 0.25
#: Errors are capped here on the curve and in paired differences (no estimate counts as this).
ERROR_CAP = 1.0
#: Bootstrap resamples.
N_BOOT = 2000
#: Modules of plate_env that do not decide an episode's outcome (left out of the code fingerprint).
NOT_OUTCOME = {"cli.py", "bench/runner.py", "plotting.py", "bench/reporting.py", "bench/scoring.py", "env/sb3.py",
               "run/executor.py", "run/sweeps.py", "build/atlas_grid.py", "build/eval_sets.py", "env/render.py",
               "bench/suites.py", "core/checks.py", "__main__.py", "env/vector.py"}


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
    probes: tuple[tuple, ...] = field(default=(), repr=False)

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

    def to_record(self, key: str) -> dict:
        return {"key": key, "index": self.index, "seed": self.seed, "omega_n_true": self.omega_n_true,
                "probe_sim_s": list(self.probe_sim_s), "prefix": [_est_record(e) for e in self.prefix],
                "decision_wall_s": list(self.decision_wall_s), "wall_s": self.wall_s,
                "probes": [list(p) for p in self.probes]}

    @classmethod
    def from_record(cls, d: dict) -> Episode:
        return cls(index=int(d["index"]), seed=int(d["seed"]), omega_n_true=float(d["omega_n_true"]),
                   probe_sim_s=tuple(d["probe_sim_s"]), prefix=tuple(_est_from(e) for e in d["prefix"]),
                   decision_wall_s=tuple(d["decision_wall_s"]), wall_s=float(d["wall_s"]),
                   probes=tuple(tuple(p) for p in d["probes"]))


def _est_record(e: Estimate) -> dict:
    return {"ok": e.ok, "method": e.method, "omega_n": e.omega_n, "ci68": list(e.omega_n_ci68),
            "ci95": list(e.omega_n_ci95), "bound": list(e.bound) if e.bound else None,
            "reason": (e.reason or "")[:300] or None}


def _est_from(d: dict) -> Estimate:
    ci68 = tuple(d["ci68"])
    return Estimate(ok=bool(d["ok"]), method=d["method"], reason=d["reason"], omega_n=float(d["omega_n"]),
                    omega_n_stderr=(ci68[1] - ci68[0]) / 2, omega_n_ci68=ci68, omega_n_ci95=tuple(d["ci95"]),
                    bound=tuple(d["bound"]) if d["bound"] else None)


def play(env, agent, obj, index: int, max_budget_s: float) -> Episode:
    """One episode of ``agent`` on ``env`` hiding suite object ``obj``: the probes until it stops or the budget
    ends, and the agent's estimate after every probe."""
    from plate_env.env.episode import estimate_model_of, estimate_of, run_episode

    res = run_episode(env, agent, seed=obj.seed, options=obj.reset_options(), max_sim_s=max_budget_s)
    t = res.probes
    fm = estimate_model_of(agent)
    prefix = tuple(estimate_of(env, t.subset(np.arange(len(t)) < k), agent.method, fm) for k in range(1, len(t) + 1))
    probes = tuple((float(f), float(a), float(w), float(s), bool(u)) for f, a, w, s, u in
                   zip(t.f_p_hz, t.a_p_deg, t.omega_b_deg_s, t.stderr_deg_s, t.unstable, strict=True))
    return Episode(index=index, seed=obj.seed, omega_n_true=obj.omega_n, probe_sim_s=res.probe_sim_s, prefix=prefix,
                   decision_wall_s=res.decision_wall_s, wall_s=res.wall_s, probes=probes)


# --------------------------------------------------------------------------------------------- fingerprints
def _sha_file(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def source_fingerprint(path: str | Path) -> str:
    """SHA-256 of a Python file's code: its syntax tree without docstrings (comments and docstrings do not
    change what it does, so editing them keeps records valid)."""
    import ast

    tree = ast.parse(Path(path).read_text())
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return hashlib.sha256(ast.dump(tree).encode()).hexdigest()


#: The package files of each physics backend (the others do not decide a suite's outcome).
PHYSICS_FILES = {"tilelink": "physics/tilelink", "pybullet": "physics/pybullet_sheet",
                 "atlas": "physics/atlas_physics.py"}


@functools.lru_cache(maxsize=8)
def code_fingerprint(physics: str) -> str:
    """SHA-256 over the package code that decides an episode's outcome on ``physics``: every module but
    :data:`NOT_OUTCOME` and the other backends (:data:`PHYSICS_FILES`), docstrings left out, and the data files
    (atlases, calibrations, forward models). Computed once per process and physics."""
    root = Path(__file__).parents[1]
    others = [root / f for name, f in PHYSICS_FILES.items() if name != physics]

    def outcome(p: Path) -> bool:
        if p.relative_to(root).as_posix() in NOT_OUTCOME:
            return False
        return not any(p == o or o in p.parents for o in others)

    files = sorted(p for p in root.rglob("*.py") if outcome(p))
    data = sorted(p for ext in ("json", "npz") for p in (root / "data").glob(f"*.{ext}"))
    h = hashlib.sha256()
    for p in files + data:
        h.update(str(p.relative_to(root)).encode())
        h.update((source_fingerprint(p) if p.suffix == ".py" else _sha_file(p)).encode())
    return h.hexdigest()


def agent_fingerprint(agent) -> dict:
    """What names an agent in a record: its class, its public options of plain types, the SHA-256 of its source
    file and, where the agent has one, its own ``fingerprint()`` (e.g. a policy's model file)."""
    cls = type(agent)
    options = {k: repr(v) for k, v in sorted(vars(agent).items()) if not k.startswith("_") and k not in
               ("context", "rng") and isinstance(v, (int, float, str, bool, tuple, type(None), Path))}
    try:
        source = source_fingerprint(inspect.getsourcefile(cls))
    except (TypeError, OSError, SyntaxError):
        source = None
    extra = agent.fingerprint() if callable(getattr(agent, "fingerprint", None)) else None
    return {"class": f"{cls.__module__}.{cls.__qualname__}", "options": options, "source": source, "extra": extra}


def run_key(suite: Suite, agent_fp: dict, max_budget_s: float) -> str:
    text = json.dumps({"format": RECORD_FORMAT, "suite": suite.sha256, "code": code_fingerprint(suite.physics),
                       "agent": agent_fp, "budget": max_budget_s}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


# --------------------------------------------------------------------------------------------- running
class _Same:
    """A factory returning one agent instance (in this process; a pickled copy in a worker)."""

    def __init__(self, agent) -> None:
        self.agent = agent

    def __call__(self):
        return self.agent


#: This process's envs, by suite content hash, and agents, by their pickled factory (a worker keeps both between
#: chunks: loading a policy through torch takes seconds; an agent starts every episode afresh by ``reset``).
_ENVS: dict[str, object] = {}
_AGENTS: dict[bytes, object] = {}


def _agent_of(factory):
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


def run_episode_chunk(backend, items: Sequence[tuple]) -> list[Episode]:
    """Executor task: play episodes ``(agent factory, suite, index, max budget)`` in this process (the env of a
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


def _load_records(path: Path, key: str) -> dict[int, Episode]:
    from plate_env.run.sweeps import read_records

    out: dict[int, Episode] = {}
    for d in read_records(path):
        if d.get("key") != key:
            continue
        try:
            out[int(d["index"])] = Episode.from_record(d)
        except (KeyError, TypeError, ValueError):
            continue  # a record of another format
    return out


@dataclass(frozen=True)
class AgentRun:
    """An agent's episodes on a suite (``episodes`` in suite order; ``limit`` set when only the first objects ran)."""

    label: str
    suite: Suite = field(repr=False)
    budgets_s: tuple[float, ...]
    episodes: tuple[Episode, ...] = field(repr=False)
    key: str = ""
    limit: int | None = None

    def summary(self, budgets_s: Sequence[float] | None = None, seed: int = 0, n_boot: int = N_BOOT) -> AgentSummary:
        return summarize(self, budgets_s, seed=seed, n_boot=n_boot)


def _check_budgets(suite: Suite, budgets_s) -> tuple[float, ...]:
    if budgets_s is None:
        return suite.budgets_s
    out = tuple(sorted({float(b) for b in budgets_s}))
    if not out or not all(math.isfinite(b) and 0 < b <= suite.max_budget_s for b in out):
        raise ValueError(f"budgets {list(budgets_s)!r}: simulated seconds in (0, {suite.max_budget_s:g}] (suite "
                         f"{suite.name}'s largest budget; a longer one is another suite version)")
    return out


def evaluate(agent, suite: Suite | str, *, label: str | None = None, budgets_s: Sequence[float] | None = None,
             executor=None, cache: str | Path | None = None, limit: int | None = None, progress: bool = False,
             chunk: int = 2) -> AgentRun:
    """Play ``agent`` on every episode of ``suite`` and return the :class:`AgentRun` (see the module docstring).

    ``agent``: an agent (:mod:`plate_env.protocol`) or a zero-argument factory of one (a picklable one, e.g.
    ``functools.partial(plate_env_agents.load_agent, "bayes")``, for process or Ray executors). ``budgets_s``:
    the budgets to score (default the suite's; each at most its largest; episodes always run to the largest).
    ``executor``: where episodes run (:func:`plate_env.executor.make_executor` names; default in-process, a process
    pool for PyBullet), ``chunk`` episodes per task. ``cache``: a JSON-lines file of finished episodes (appended as
    they finish; a rerun resumes). ``limit``: only the first ``limit`` objects (quick looks; not the suite's result).
    Ctrl-C raises :class:`BenchInterrupted` after the finished episodes are written.
    """
    from plate_env.run.executor import BackendSpec, check_executor_name, make_executor
    from plate_env.run.sweeps import open_for_append

    suite = load_suite(suite) if isinstance(suite, str) else suite
    budgets = _check_budgets(suite, budgets_s)
    n = len(suite.objects) if limit is None else min(int(limit), len(suite.objects))
    if n < 1:
        raise ValueError(f"limit = {limit!r}: at least one object")
    factory = agent if (callable(agent) and not hasattr(agent, "next_probe")) else _Same(agent)
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
            from tqdm.auto import tqdm

            bar = tqdm(total=n, initial=n - len(todo), desc=f"{label} on {suite.name}", unit="episode")
        fh = open_for_append(path) if path else None
        try:
            for _, episodes in ex.map(backend, chunks, task=run_episode_chunk):
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


# --------------------------------------------------------------------------------------------- scoring
@dataclass(frozen=True)
class BudgetScores:
    """An agent's scores at one budget: :class:`~plate_env.scoring.Scores`, mean probes, median seconds used."""

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
    budgets = _check_budgets(run.suite, budgets_s if budgets_s is not None else run.budgets_s)
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


# --------------------------------------------------------------------------------------------- leaderboard
def _pct(s: Stat, digits: int = 1) -> str:
    if not math.isfinite(s.value):  # inf, or nan (a quantile between no-estimates): beyond every estimate
        return "none"
    hi = f"{100 * s.hi:.{digits}f}" if math.isfinite(s.hi) else "inf"
    return f"{100 * s.value:.{digits}f} [{100 * s.lo:.{digits}f}, {hi}]"


def rank(summaries: Sequence[AgentSummary]) -> list[AgentSummary]:
    """Best first: by the area of the median-error curve."""
    return sorted(summaries, key=lambda s: (s.area.value, s.label))


def paired_table(runs: dict[str, AgentRun], leader: str, budgets: Sequence[float], seed: int = 0) -> dict:
    """``{label: {budget: Stat}}``: each agent's paired difference against ``leader`` at each budget."""
    return {label: {b: compare(run, runs[leader], b, seed) for b in budgets}
            for label, run in runs.items() if label != leader}


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


__all__ = ["AgentRun", "AgentSummary", "BenchInterrupted", "Episode", "board", "board_to_dict", "compare", "evaluate",
           "leaderboard_markdown", "summarize"]
