"""Run an agent for one episode of PlateRotation-v0 and score its estimate."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from agents.base import Agent, Probe, ProbeContext
from plate_env.estimate import Estimate
from plate_env.identify import identify
from plate_env.probes import ProbeTable


@dataclass(frozen=True)
class EpisodeResult:
    """One identification: the truth, the agent's estimate (by its own method), and what the probing cost."""

    agent: str
    omega_n_true: float
    alpha_true: float
    estimate: Estimate
    probes: ProbeTable = field(repr=False)
    n_probes: int
    sim_s: float
    wall_s: float

    @property
    def relative_error(self) -> float:
        return self.estimate.relative_error(self.omega_n_true)

    def to_dict(self) -> dict:
        return {"agent": self.agent, "omega_n_true_rad_s": self.omega_n_true, "alpha_true_deg":
                float(np.degrees(self.alpha_true)), "relative_error": self.relative_error if self.estimate.ok
                else None, "n_probes": self.n_probes, "sim_s": self.sim_s, "wall_s": self.wall_s,
                "estimate": self.estimate.to_dict(), "probes": self.probes.to_rows()}


def run_episode(env, agent: Agent, seed: int, options: dict | None = None,
                on_probe: Callable[[int, dict], None] | None = None) -> EpisodeResult:
    """Reset ``env`` with ``seed`` (and ``options``: omega_n, alpha, mass), let ``agent`` probe until it stops or
    the budget ends, then estimate omega_n with the agent's method."""
    t0 = time.perf_counter()
    e = env.unwrapped
    obs, info = env.reset(seed=seed, options=options)
    agent.reset(ProbeContext.from_env(env), np.random.default_rng(seed))
    terminated = truncated = False
    while not (terminated or truncated):
        choice = agent.next_probe(e.table(), obs)
        if choice is None:
            if len(e.table()) == 0:
                raise RuntimeError(f"agent {agent.name} stopped before its first probe")
            action = e.encode_action(stop=True)
        elif isinstance(choice, Probe):
            action = e.encode_action(choice.f_p_hz, choice.a_p_deg, choice.measure_s)
        else:
            action = np.asarray(choice, dtype=np.float32)
        obs, _, terminated, truncated, info = env.step(action)
        if on_probe is not None and "last_probe" in info and (choice is not None):
            on_probe(info["probes"], info["last_probe"])
    table = e.table()
    try:
        est = identify(table, method=agent.method, physics=e.source, model=e.model, known=e.known_inputs(),
                       forward=agent.estimate_model())
    except ValueError as exc:
        est = Estimate(ok=False, method=agent.method, reason=str(exc))
    return EpisodeResult(agent=agent.name, omega_n_true=info["omega_n_true"], alpha_true=info["alpha_true"],
                         estimate=est, probes=table, n_probes=len(table), sim_s=info["sim_s"],
                         wall_s=time.perf_counter() - t0)
