"""Probing agents: the paper's grid sweep, a coarse-to-fine heuristic, Bayesian design, a trained PPO policy."""

from __future__ import annotations

from agents.base import Agent, Probe, ProbeContext

AGENT_NAMES = ("grid", "coarse_to_fine", "bayes", "ppo")


def make_agent(name: str, **options) -> Agent:
    """Create an agent by name; options go to its constructor."""
    if name == "grid":
        from agents.grid import GridAgent

        return GridAgent(**options)
    if name == "coarse_to_fine":
        from agents.coarse_to_fine import CoarseToFineAgent

        return CoarseToFineAgent(**options)
    if name == "bayes":
        from agents.bayes import BayesAgent

        return BayesAgent(**options)
    if name == "ppo":
        from agents.ppo import PPOAgent

        return PPOAgent(**options)
    raise ValueError(f"unknown agent {name!r}; choose one of {AGENT_NAMES}")


__all__ = ["AGENT_NAMES", "Agent", "Probe", "ProbeContext", "make_agent"]
