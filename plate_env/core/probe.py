"""The values that cross the physics interface (:mod:`plate_env.physics.interface`): what a probe is
(:class:`ProbeSpec`), what it returns (:class:`ProbeResult`, :class:`Status`), and the checks every probe passes."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectSpec


class Status(IntEnum):
    """How a probe ended: ``OK``, or the reason it is unstable. One encoding for every backend.

    The numba kernels return the code (an ``int``); a :class:`ProbeResult` carries ``Status(code).reason``, the
    reason string (``None`` for ``OK``).
    """

    reason: str | None

    def __new__(cls, code: int, reason: str | None) -> Status:
        member = int.__new__(cls, code)
        member._value_ = code
        member.reason = reason
        return member

    OK = 0, None
    #: the disc turned upside down
    OVERTURNED = 1, "overturned"
    #: its centre moved more than ``slip_limit`` from the plate centre (plate frame)
    SLIPPED = 2, "slipped"
    #: NaN or inf in the state (e.g. too large a time step)
    NON_FINITE = 3, "non_finite"
    #: a node moved faster than the plate could ever make it, or the energy grew beyond the plate's work
    RUNAWAY = 4, "runaway_energy"
    #: the disc flew far above the plate or sank through it
    LEFT_PLATE = 5, "left_plate"
    #: the disc folded onto itself
    FOLDED = 6, "folded"


# The reason strings, for backends that report reasons directly (pybullet, atlas).
OVERTURNED = Status.OVERTURNED.reason
SLIPPED = Status.SLIPPED.reason
NON_FINITE = Status.NON_FINITE.reason
RUNAWAY = Status.RUNAWAY.reason
LEFT_PLATE = Status.LEFT_PLATE.reason
FOLDED = Status.FOLDED.reason
REASONS = tuple(s.reason for s in Status if s.reason is not None)

#: The paper's instability test: centre more than 10 mm from the plate centre.
SLIP_LIMIT_M = 0.010
#: Lowest plate frequency a probe accepts, Hz, and the longest probe, simulated s.
MIN_PROBE_FREQ_HZ = 0.5
MAX_PROBE_S = 1200.0
#: Most time steps one probe may take (a larger dt or shorter windows beyond): ~20 s of wall time a point-mass
#: probe, minutes a rigid one; dt = 1e-9 s would ask 1.7e9 steps of the default probe and run for hours.
MAX_PROBE_STEPS = 10_000_000
#: Allowed settle and measurement windows of a probe, s (the measurement window open at 0).
WINDOW_RANGE_S = (0.0, 600.0)
#: Default placement error (std per axis) of a repeated probe, m.
PLACEMENT_STD_M = 2e-4


@dataclass(frozen=True)
class ProbeSpec:
    """One probe: an object on a plate moving one way, measured over a window.

    The plate ramps up over ``motion.ramp_s``, the disc settles for ``settle_s`` more, then omega_B is measured
    over ``measure_s`` rounded to whole plate periods (at least 2). Times in seconds. The disc starts flat at
    rest, turned by ``initial_yaw`` (rad) and shifted by ``initial_offset`` (u, v in m, plate frame).
    How the default windows (0.5 s, 1.0 s) compare with 3 s + 6 s windows is measured in
    ``experiments/results/bench_physics.md`` (``experiments/bench_physics.py``).
    ``record_trace`` keeps the yaw trace in the result (for camera models and plots).
    """

    obj: ObjectSpec
    motion: PlateMotion
    settle_s: float = 0.5
    measure_s: float = 1.0
    record_trace: bool = False
    initial_yaw: float = 0.0
    initial_offset: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        lo, hi = WINDOW_RANGE_S
        for label, value in (("settle_s", self.settle_s), ("measure_s", self.measure_s)):
            opened = label == "measure_s"  # a window of 0 s measures nothing (it was measured as 2 periods)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and (lo < value if opened else
                                                                                   lo <= value) and value <= hi):
                raise ValueError(f"ProbeSpec {label} = {value!r} is outside the allowed range "
                                 f"{'(' if opened else '['}{lo:g}, {hi:g}] s")
        if not (self.motion.freq_hz >= MIN_PROBE_FREQ_HZ):
            raise ValueError(f"a probe needs a plate frequency f_p >= {MIN_PROBE_FREQ_HZ} Hz (whole periods are "
                             f"measured), got {self.motion.freq_hz!r}")
        if self.duration_s > MAX_PROBE_S:
            raise ValueError(f"the probe would last {self.duration_s:.0f} simulated s; at most {MAX_PROBE_S:.0f} s")
        if not (math.isfinite(self.initial_yaw) and abs(self.initial_yaw) <= 2 * math.pi):
            raise ValueError(f"ProbeSpec initial_yaw = {self.initial_yaw!r} rad is outside [-2pi, 2pi]")
        if len(self.initial_offset) != 2 or not all(
                math.isfinite(x) and abs(x) <= SLIP_LIMIT_M for x in self.initial_offset):
            raise ValueError(f"ProbeSpec initial_offset = {self.initial_offset!r} m must be two values within "
                             f"+-{SLIP_LIMIT_M} m")

    def perturbed(self, rng: np.random.Generator, offset_std: float = PLACEMENT_STD_M) -> ProbeSpec:
        """The same probe repeated as a real experiment would be: the disc placed at a random yaw (uniform over
        the tile grid's quarter-turn symmetry) and a random offset (normal, ``offset_std`` m per axis, clipped).

        The tile-link disc's centred position is an unstable equilibrium at most frequencies: the share of
        probes that slip 10 mm (A_p = 3 deg, 14-26 Hz, 15pi) was 0/48 centred, 11/48 with 0.2 mm and 36/48 with
        1 mm placement error. The default 0.2 mm is a careful robot placement."""
        du, dv = rng.normal(0.0, offset_std, 2).tolist()
        lim = 0.5 * SLIP_LIMIT_M
        offset = (min(max(du, -lim), lim), min(max(dv, -lim), lim))  # np.clip's values (normal draws: no NaN)
        return ProbeSpec(self.obj, self.motion, self.settle_s, self.measure_s, self.record_trace,
                         initial_yaw=float(rng.uniform(0.0, math.pi / 2)), initial_offset=offset)

    @property
    def measure_start_s(self) -> float:
        return self.motion.ramp_s + self.settle_s

    @property
    def n_periods(self) -> int:
        return max(2, int(round(self.measure_s * self.motion.freq_hz)))

    @property
    def duration_s(self) -> float:
        """Simulated seconds the probe needs: ramp + settle + whole measurement periods."""
        return self.measure_start_s + self.n_periods / self.motion.freq_hz


@dataclass(frozen=True)
class YawTrace:
    """The disc's unwrapped yaw about the plate normal (rad) and its centre in the plate frame (m) over time (s)."""

    t: np.ndarray
    yaw: np.ndarray
    centre_u: np.ndarray
    centre_v: np.ndarray


@dataclass(frozen=True)
class ProbeResult:
    """What a probe measured.

    ``omega_b_deg_s`` is signed (counter-clockwise about the plate normal positive) and averaged over whole
    plate periods of the measurement window; ``stderr_deg_s`` is its standard error from batch means. For an
    unstable probe both describe the whole periods completed before the failure (0.0 if there were none) and
    must not be fitted; ``reason`` says what went wrong. No field is ever NaN.
    """

    spec: ProbeSpec
    omega_b_deg_s: float
    stderr_deg_s: float
    unstable: bool
    reason: str | None
    sim_s: float
    wall_s: float
    periods_measured: int
    trace: YawTrace | None = field(default=None, compare=False, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary in edge units."""
        return {
            "f_p_hz": self.spec.motion.freq_hz,
            "a_p_deg": math.degrees(self.spec.motion.amp_rad),
            "b_p_mm": self.spec.motion.b_p * 1e3,
            "omega_n_rad_s": self.spec.obj.omega_n,
            "alpha_deg": math.degrees(self.spec.obj.alpha),
            "mass_g": self.spec.obj.mass * 1e3,
            "omega_b_deg_s": self.omega_b_deg_s,
            "stderr_deg_s": self.stderr_deg_s,
            "unstable": self.unstable,
            "reason": self.reason,
            "sim_s": self.sim_s,
            "wall_s": self.wall_s,
            "periods_measured": self.periods_measured,
        }


class ProbeRefused(ValueError):
    """A backend cannot answer a probe; raised before any work. ``quantity`` names the probe's value at fault
    (``f_p_hz``, ``a_p_deg``, ``omega_n``, ``alpha``, ``b_p``, ``mass``, ``diameter``, ``steps``), so a caller that
    generated the probe from its own options can say which option to change."""

    def __init__(self, quantity: str, message: str) -> None:
        super().__init__(message)
        self.quantity = quantity


def check_step_counts(probes: Sequence[ProbeSpec], dt: float) -> None:
    """Refuse (ProbeRefused, quantity ``steps``) a probe that would take more than :data:`MAX_PROBE_STEPS` steps
    of ``dt`` s."""
    for i, spec in enumerate(probes):
        steps = spec.duration_s / dt
        if steps > MAX_PROBE_STEPS:
            raise ProbeRefused("steps", f"probe {i}: {steps:.3g} time steps of dt = {dt:g} s for "
                                        f"{spec.duration_s:.4g} simulated s; at most {MAX_PROBE_STEPS:.0e} a probe "
                                        f"(use a larger dt or shorter windows)")


def check_probes(probes: Sequence[ProbeSpec]) -> list[ProbeSpec]:
    """The probes as a list, each checked to be a ProbeSpec (TypeError naming the first that is not)."""
    probes = list(probes)
    for i, s in enumerate(probes):
        if not isinstance(s, ProbeSpec):
            raise TypeError(f"probe {i}: expected ProbeSpec, got {type(s).__name__}")
    return probes
