"""One interface for every probing agent: given the probes so far, propose the next probe or stop."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from plate_env.forward import KnownInputs
from plate_env.probes import ProbeTable


@dataclass(frozen=True)
class Probe:
    """A probe an agent asks for: plate frequency (Hz), amplitude (deg, one the env offers), window (s)."""

    f_p_hz: float
    a_p_deg: float
    measure_s: float = 1.0


@dataclass(frozen=True)
class ProbeContext:
    """What an agent may know about the task (not the hidden object).

    Attributes: f_band_hz, amplitudes_deg, measure_range_s, max_probes, max_sim_s (or None), overhead_s (ramp +
    settle, the simulated seconds every probe costs besides its window), physics/model (whose forward model and
    calibration apply), known (what a lab knows: B_p, the disc's mass and diameter).
    """

    f_band_hz: tuple[float, float]
    amplitudes_deg: tuple[float, ...]
    measure_range_s: tuple[float, float]
    max_probes: int
    max_sim_s: float | None
    overhead_s: float
    physics: str
    model: str
    known: KnownInputs = KnownInputs()

    @classmethod
    def from_env(cls, env) -> ProbeContext:
        e = env.unwrapped
        return cls(f_band_hz=e.f_band_hz, amplitudes_deg=e.amplitudes_deg, measure_range_s=e.measure_range_s,
                   max_probes=e.max_probes, max_sim_s=e.max_sim_s, overhead_s=0.2 + e.settle_s, physics=e.source,
                   model=e.model, known=e.known_inputs())


class Agent(ABC):
    """A probing policy. ``method`` is how its probes are turned into an estimate ("lorentz" or "atlas")."""

    name: str = "agent"
    method: str = "atlas"

    def reset(self, context: ProbeContext, rng: np.random.Generator) -> None:
        """Start a new episode (no probes yet)."""
        self.context = context
        self.rng = rng

    @abstractmethod
    def next_probe(self, history: ProbeTable, obs: np.ndarray | None = None) -> Probe | None:
        """The next probe to run, or None to stop and estimate."""

    def estimate_model(self):
        """The forward model (:class:`plate_env.forward.ForwardModel`) the episode's estimate must use, or None for
        the shipped one of the episode's physics: an agent that chose its probes on a model says so here."""
        return None
