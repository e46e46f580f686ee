"""One identification episode: an agent probes a PlateRotation-v0 env until it stops or the budget ends, then its
probes are turned into an estimate by the agent's method. The one episode loop of the CLI, the benchmark and the
experiment scripts."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from plate_env.core.probe_table import ProbeTable
from plate_env.env.protocol import Probe, ProbeContext, ProbingAgent
from plate_env.identify.estimate import Estimate

if TYPE_CHECKING:
    from plate_env.identify.estimators import Estimator
    from plate_env.identify.forward import ForwardModel

#: The env argument of these functions: a ``PlateRotation-v0`` env, made by ``gym.make`` (wrapped) or directly; its
#: ``unwrapped`` is a :class:`~plate_env.env.rotation.PlateRotationEnv` (not typed here while that class is
#: refactored, issue 35).
EnvLike = Any


@dataclass(frozen=True)
class EpisodeResult:
    """One identification: the truth, the agent's estimate (by its own method), and what the probing cost.

    ``probe_sim_s``: simulated seconds of each probe in order (ramp + settle + window, less if it ended unstable);
    ``decision_wall_s``: wall seconds of each ``next_probe`` call (the last one may be the decision to stop);
    ``prefix``: the estimate after each probe when asked for (``run_episode(prefix=True)``).
    """

    agent: str
    omega_n_true: float
    alpha_true: float
    estimate: Estimate
    probes: ProbeTable = field(repr=False)
    n_probes: int
    sim_s: float
    wall_s: float
    probe_sim_s: tuple[float, ...] = ()
    decision_wall_s: tuple[float, ...] = ()
    prefix: tuple[Estimate, ...] = field(default=(), repr=False)

    @property
    def relative_error(self) -> float:
        return self.estimate.relative_error(self.omega_n_true)

    def to_dict(self) -> dict[str, Any]:
        return {"agent": self.agent, "omega_n_true_rad_s": self.omega_n_true, "alpha_true_deg":
                float(np.degrees(self.alpha_true)), "relative_error": self.relative_error if self.estimate.ok
                else None, "n_probes": self.n_probes, "sim_s": self.sim_s, "wall_s": self.wall_s,
                "estimate": self.estimate.to_dict(), "probes": self.probes.to_rows()}


def estimate_model_of(agent: ProbingAgent) -> ForwardModel | None:
    """The forward model ``agent``'s estimates use (``agent.estimate_model()``; None, the physics' shipped one,
    for an agent without that method)."""
    f = getattr(agent, "estimate_model", None)
    model: ForwardModel | None = f() if callable(f) else None
    return model


def estimator_of(env: EnvLike, agent: ProbingAgent) -> Estimator:
    """The :class:`~plate_env.identify.estimators.Estimator` of ``agent``'s estimates in ``env``'s episode
    (:func:`plate_env.identify.estimators.agent_estimator`: its own forward model's, else the env's estimator when
    the agent's method is the env's, else its method's)."""
    from plate_env.identify.estimators import ForwardName, agent_estimator

    e = env.unwrapped
    return agent_estimator(getattr(agent, "method", "atlas"), estimate_model_of(agent), e.method, e.estimator(),
                           ForwardName(e.source, e.model), e.known_inputs())


def _estimator(env: EnvLike, method: str, forward: ForwardModel | str | None = None) -> Estimator:
    from plate_env.identify.estimators import ForwardName, make_estimator

    e = env.unwrapped
    return make_estimator(method, ForwardName(e.source, e.model), e.known_inputs(), forward=forward)


def estimate_of(env: EnvLike, table: ProbeTable, method: str, forward: ForwardModel | str | None = None) -> Estimate:
    """``method``'s estimate from ``table`` for ``env``'s physics and known inputs, on ``forward`` (a forward model,
    or None for the physics' shipped one); no estimate, with the reason, when the method cannot make one. (The
    estimator's :func:`~plate_env.identify.estimators.fit_or_refuse`; an estimator in hand: call that.)"""
    from plate_env.identify.estimators import fit_or_refuse

    return fit_or_refuse(_estimator(env, method, forward), table)


def estimator_prefixes(estimator: Estimator, table: ProbeTable) -> tuple[Estimate, ...]:
    """``estimator``'s estimate after each probe of ``table`` (as ``fit_or_refuse`` of each prefix gives it): from
    one incremental posterior (``estimator.start()``) the probes are added to one by one when it has one (each
    prefix costs one pooling, not a recomputation of every probe's likelihood), else each prefix fitted anew."""
    from plate_env.identify.estimators import fit_or_refuse

    try:
        state = estimator.start()
    except ValueError as exc:
        return tuple(Estimate(ok=False, method=estimator.method, reason=str(exc)) for _ in range(len(table)))
    if state is None:
        return tuple(fit_or_refuse(estimator, table.subset(np.arange(len(table)) < k))
                     for k in range(1, len(table) + 1))
    prefixes: tuple[Estimate, ...] = state.prefix_estimates(table)
    return prefixes


def prefix_estimates(env: EnvLike, table: ProbeTable, method: str,
                     forward: ForwardModel | str | None = None) -> tuple[Estimate, ...]:
    """``method``'s estimate after each probe of ``table`` (:func:`estimator_prefixes` of its estimator)."""
    return estimator_prefixes(_estimator(env, method, forward), table)


def _step(env: EnvLike, agent: ProbingAgent,
          choice: Probe | np.ndarray | None) -> tuple[Any, float, bool, bool, dict[str, Any]]:
    """``env.step`` of an agent's answer (ValueError naming the agent for an answer the env refuses; the env is
    left as it was)."""
    e = env.unwrapped
    try:
        if choice is None:
            action = e.encode_action(stop=True)
        elif isinstance(choice, Probe):
            action = e.encode_action(choice.f_p_hz, choice.a_p_deg, choice.measure_s)
        else:
            action = np.asarray(choice, dtype=np.float32)
        stepped: tuple[Any, float, bool, bool, dict[str, Any]] = env.step(action)  # checked before anything runs
        return stepped
    except ValueError as exc:
        raise ValueError(f"agent {agent.name!r}: next_probe returned {choice!r}: {exc}") from None


class AgentError(ValueError):
    """An agent failed (raised, exited, stopped before its first probe): the message names it. A ValueError, so the
    command line answers it as the user's input (exit 2), not as a bug of plate-env."""


def _call(agent: object, method: str, *args: Any) -> Any:
    """``agent.<method>(*args)``, its failures (an exception, ``sys.exit``) as :class:`AgentError` naming it."""
    try:
        return getattr(agent, method)(*args)
    except AgentError:
        raise
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - a user's agent may raise anything; Ctrl-C passes
        name = getattr(agent, "name", type(agent).__name__)
        raise AgentError(f"agent {name!r} failed in {method}: {type(exc).__name__}: {exc}") from None


def run_episode(env: EnvLike, agent: ProbingAgent, seed: int, options: dict[str, Any] | None = None,
                on_probe: Callable[[int, dict[str, Any]], None] | None = None,
                max_sim_s: float | None = None, prefix: bool = False) -> EpisodeResult:
    """Reset ``env`` with ``seed`` (and ``options``: omega_n, alpha, mass), let ``agent`` probe until it stops, the
    env's budget ends or the probes have taken ``max_sim_s`` simulated seconds (a budget enforced here, without
    changing the env's observation; the agent's context names it), then estimate omega_n with the agent's method.
    ``on_probe(k, probe_dict)`` is called after each probe. ``prefix``: also the estimate after each probe
    (:func:`estimator_prefixes`, in ``EpisodeResult.prefix``; the last is the episode's estimate). Otherwise the
    env's own estimate is reused when the agent's estimator (:func:`estimator_of`) is the env's atlas estimator. An
    agent's estimate model (``agent.estimate_model()``) is handed to the env after reset (``use_estimate_model``):
    the estimate the env's reward charges is this result's, the same floats (method atlas, no lab calibration)."""
    t0 = time.perf_counter()
    e = env.unwrapped
    obs, info = env.reset(seed=seed, options=options)
    _call(agent, "reset", ProbeContext.from_env(env, max_sim_s), np.random.default_rng(seed))
    from plate_env.identify.estimators import AtlasEstimator, ForwardName, agent_estimator

    fm = estimate_model_of(agent)
    # one estimate for the env's reward and this result: when the agent estimates by the env's atlas estimator (no
    # lab calibration), its estimate model is the env's for this episode
    env_estimator = e.estimator()
    shared = isinstance(env_estimator, AtlasEstimator) and agent_estimator(
        getattr(agent, "method", "atlas"), None, e.method, env_estimator, ForwardName(e.source, e.model),
        e.known_inputs()) is env_estimator
    if shared and fm is not None:
        e.use_estimate_model(fm)
    sims: list[float] = []
    decisions: list[float] = []
    done = False
    while not done and not (max_sim_s is not None and info["sim_s"] >= max_sim_s):
        table = e.table()
        t = time.perf_counter()
        choice = _call(agent, "next_probe", table, obs)
        decisions.append(time.perf_counter() - t)
        if choice is None and len(table) == 0:
            raise AgentError(f"agent {agent.name!r} stopped before its first probe (an episode needs at least one)")
        obs, _, terminated, truncated, info = _step(env, agent, choice)
        done = terminated or truncated
        if info["probes"] > len(sims):
            sims.append(float(info["last_probe"]["sim_s"]))
            if on_probe is not None:
                on_probe(info["probes"], info["last_probe"])
    table = e.table()
    estimator = estimator_of(env, agent)
    prefixes: tuple[Estimate, ...] = ()
    if prefix and len(table):
        prefixes = estimator_prefixes(estimator, table)
        estimate = prefixes[-1]
    elif shared:
        estimate = e.estimate()  # the env's own posterior of these probes (on fm; its episode end computed it)
    else:
        from plate_env.identify.estimators import fit_or_refuse

        estimate = fit_or_refuse(estimator, table)
    # the truth from the env, not the info: a budget of max_sim_s ends the episode here before the env terminates it
    # (the info shows the hidden object on the terminating step only)
    obj = e.hidden_object()
    return EpisodeResult(agent=agent.name, omega_n_true=obj.omega_n, alpha_true=obj.alpha,
                         estimate=estimate, probes=table, prefix=prefixes,
                         n_probes=len(table),
                         sim_s=float(info["sim_s"]), wall_s=time.perf_counter() - t0, probe_sim_s=tuple(sims),
                         decision_wall_s=tuple(decisions))
