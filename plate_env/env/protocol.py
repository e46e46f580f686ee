"""The probing-agent protocol: what an agent is given (:class:`ProbeContext`, the probe table, the env's
observation) and what it answers (a :class:`Probe`, an env action, or None to stop).

It lives in the library core so that the episode loop (:mod:`plate_env.env.episode`), the benchmark
(:mod:`plate_env.bench.runner`) and third-party agents depend on it without importing the shipped agents
(``plate_env_agents``, which subclass :class:`Agent`).

An agent is any object with

* ``name`` (str) and ``method`` (``"atlas"``: the forward model's posterior, or ``"lorentz"``: the paper's fit),
  how its probes are turned into an estimate: the episode loop reads it, with ``estimate_model()`` when the agent
  has one, once into an :class:`~plate_env.identify.estimators.Estimator`
  (:func:`plate_env.env.episode.estimator_of`);
* ``reset(context, rng)``: a new episode starts (no probes yet); ``rng`` is the episode's seeded generator, the
  only randomness an agent may use;
* ``next_probe(history, obs)``: given the probes so far (a :class:`~plate_env.core.probe_table.ProbeTable`, in the order
  they ran) and the env's observation, return the next :class:`Probe`, a raw env action (4 numbers in [-1, 1]), or
  None to stop and estimate.

Subclassing :class:`Agent` is optional (:func:`check_agent` checks the duck type).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numpy as np

from plate_env.core import checks
from plate_env.core.probe import WINDOW_RANGE_S
from plate_env.core.probe_table import ProbeTable
from plate_env.core.setup import AMP_RANGE_RAD
from plate_env.identify.api import METHODS
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.identify.forward import ForwardModel

#: The estimators an agent may name as its ``method``.
AGENT_METHODS = METHODS


def probe_options(a_p_deg: object, measure_s: object) -> tuple[float, float]:
    """An agent's fixed probe amplitude (deg, within +-45) and window (s, in (0, 600]) checked in its constructor:
    ValueError naming the option and its range (a string or NaN from ``name:key=value`` never reaches a probe)."""
    amp = math.degrees(AMP_RANGE_RAD[1])
    return (checks.real("a_p_deg", a_p_deg, -amp, amp, unit="deg"),
            checks.real("measure_s", measure_s, *WINDOW_RANGE_S, open_lo=True, unit="s"))


@dataclass(frozen=True)
class Probe:
    """A probe an agent asks for: plate frequency (Hz), amplitude (deg, one the env offers), window (s)."""

    f_p_hz: float
    a_p_deg: float
    measure_s: float = 1.0


@dataclass(frozen=True)
class ProbeContext:
    """What an agent may know about the task (not the hidden object).

    Attributes: f_band_hz, amplitudes_deg, measure_range_s, max_probes, max_sim_s (the probing budget in simulated
    seconds, or None), overhead_s (ramp + settle, the simulated seconds every probe costs besides its window),
    physics/model (whose forward model and calibration apply), known (what a lab knows: B_p, the disc's mass and
    diameter).
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
    def from_env(cls, env: Any, max_sim_s: float | None = None) -> ProbeContext:
        """The context of ``env``'s current episode; ``max_sim_s`` (a budget the caller enforces) tightens the
        env's own."""
        e = env.unwrapped
        budgets = [b for b in (e.max_sim_s, max_sim_s) if b is not None]
        return cls(f_band_hz=e.f_band_hz, amplitudes_deg=e.amplitudes_deg, measure_range_s=e.measure_range_s,
                   max_probes=e.max_probes, max_sim_s=min(budgets) if budgets else None,
                   overhead_s=0.2 + e.settle_s, physics=e.source, model=e.model, known=e.known_inputs())


class Agent(ABC):
    """A probing policy (see the module docstring). Subclasses implement :meth:`next_probe`."""

    name: str = "agent"
    method: str = "atlas"
    #: The shipped forward model (``"tilelink/pointmass"``, ``"lab"``, ...: :func:`plate_env.identify.forward.
    #: load_forward_model`'s names) the episode's estimate is made through, conditioned on the episode's known
    #: inputs; None: the episode physics' own. Set it to read episodes through another physics than theirs (the
    #: misspecification track: ``plate-env bench --agent grid:method=atlas,forward=lab``).
    forward: str | None = None

    def reset(self, context: ProbeContext, rng: np.random.Generator) -> None:
        """Start a new episode (no probes yet)."""
        self.context = context
        self.rng = rng

    @abstractmethod
    def next_probe(self, history: ProbeTable, obs: np.ndarray | None = None) -> Probe | np.ndarray | None:
        """The next probe to run (a :class:`Probe` or a raw env action), or None to stop and estimate."""

    def estimate_model(self) -> ForwardModel | None:
        """The forward model (:class:`~plate_env.identify.forward.ForwardModel`) the episode's estimate must use, or
        None for the shipped one of the episode's physics: an agent that chose its probes on a model says so here.
        The base class answers :attr:`forward`'s model (None when it is None)."""
        if self.forward is None:
            return None
        from plate_env.identify.forward import load_forward_model

        return load_forward_model(self.forward, self.context.known)


class ProbingAgent(Protocol):
    """The duck type of an agent (the module docstring; :func:`check_agent` checks it at run time): ``name``,
    ``reset`` and ``next_probe``; ``method`` (default ``"atlas"``) and ``estimate_model()`` are optional."""

    @property
    def name(self) -> str: ...

    def reset(self, context: ProbeContext, rng: np.random.Generator) -> None: ...

    def next_probe(self, history: ProbeTable, obs: np.ndarray | None = None) -> Probe | np.ndarray | None: ...


_A = TypeVar("_A")


def check_agent(agent: _A, where: str = "agent") -> _A:
    """``agent`` if it follows the protocol (callable ``reset`` and ``next_probe``, a string ``name``, ``method``
    one of :data:`AGENT_METHODS`), else ValueError naming ``where`` and what is missing."""
    missing = [m for m in ("reset", "next_probe") if not callable(getattr(agent, m, None))]
    if missing:
        raise ValueError(f"{where}: {type(agent).__name__} has no method(s) {missing}; an agent needs "
                         "reset(context, rng) and next_probe(history, obs) (see plate_env.env.protocol)")
    if not isinstance(getattr(agent, "name", None), str):
        raise ValueError(f"{where}: {type(agent).__name__}.name must be a string")
    method = getattr(agent, "method", "atlas")
    if method not in AGENT_METHODS:
        raise ValueError(f"{where}: {type(agent).__name__}.method = {method!r}; choose one of {AGENT_METHODS}")
    return agent
