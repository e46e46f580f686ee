"""The paper's set-up and the allowed ranges of a disc and a plate: one home for both (SI inside).

:data:`PAPER_SETUP` is the paper's experiment (Section 6): the cheese slice of 13.6 g and 80 mm on a plate moving
with B_p = 3 mm. Every default that means "the paper's set-up" (an :class:`~plate_env.core.objects.ObjectSpec`, a
:class:`~plate_env.core.motion.PlateMotion`, a lab's known inputs, the atlases' build inputs, the env and the
command line) reads it from here.

The ranges below are what any part of the package accepts; a value outside is refused naming the value and the
range, before any work:

* mass :data:`MASS_RANGE_KG` = [0.1 g, 1 kg]. One range for the object, a lab's known inputs and the command line
  (they disagreed: (0, 10 kg], [0.1 g, 1 kg] and [0.1, 1000] g). The paper's objects weigh 6.9-39.5 g; the range
  spans two decades below the lightest and 25 times the heaviest. A 10 kg disc of 80 mm (a steel puck a quarter
  metre thick) is no thin deformable object, and a mass of zero has no friction force to turn it; both are refused
  rather than simulated.
* diameter :data:`DIAMETER_RANGE_M` = [10 mm, 500 mm] (the known inputs' range; the object's was (0, 1 m]).
* plate: :data:`FREQ_RANGE_HZ`, :data:`AMP_RANGE_RAD` (|A_p| <= 45 deg), :data:`B_P_RANGE_M` (|B_p| <= 50 mm);
  a lab's known B_p is a magnitude in :data:`KNOWN_B_P_RANGE_M` (a plate that does not move linearly turns no disc).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Allowed mass of an object, kg (closed).
MASS_RANGE_KG = (1e-4, 1.0)
#: Allowed diameter of an object, m (closed).
DIAMETER_RANGE_M = (0.01, 0.5)
#: Allowed ranges of the plate's parameters (inclusive), in SI units.
FREQ_RANGE_HZ = (0.0, 200.0)
AMP_RANGE_RAD = (-math.radians(45.0), math.radians(45.0))
B_P_RANGE_M = (-0.05, 0.05)
#: Allowed magnitude of a lab's known B_p, m (closed).
KNOWN_B_P_RANGE_M = (1e-4, B_P_RANGE_M[1])
#: Allowed probe budget of an episode (PlateRotation-v0's ``max_probes``, ``identify --max-probes``; closed). Its upper
#: end is the registered env spec's ``max_episode_steps``: a bound the env never reaches before it terminates itself.
MAX_PROBES_RANGE = (1, 500)
#: Seeds of an episode (the env, the agents, a suite's objects, ``identify --seed``): numpy's SeedSequence takes
#: non-negative integers; closed.
SEED_RANGE = (0, 2 ** 63 - 1)


@dataclass(frozen=True)
class PaperSetup:
    """The paper's set-up (SI): B_p (m), the cheese slice's mass (kg) and diameter (m). The ``*_mm``/``*_g``
    properties are the same values at the edges (rounded to 9 decimals, so 13.6 g is the float 13.6)."""

    b_p: float = 0.003
    mass: float = 0.0136
    diameter: float = 0.080

    @property
    def b_p_mm(self) -> float:
        return round(self.b_p * 1e3, 9)

    @property
    def mass_g(self) -> float:
        return round(self.mass * 1e3, 9)

    @property
    def diameter_mm(self) -> float:
        return round(self.diameter * 1e3, 9)


#: The probe budget of an episode when none is given: the one default of the env, the CLI, the suites and the
#: shipped policy (the observation's length, 7 * max_probes + 2, depends on it). Here, not in the env, so that the
#: command line reads it without importing gymnasium.
DEFAULT_MAX_PROBES = 30
#: The paper's set-up: B_p 3 mm, the 13.6 g, 80 mm cheese slice.
PAPER_SETUP = PaperSetup()


def in_range(value: object, lo: float, hi: float) -> bool:
    """Whether ``value`` is a finite real number (not a bool) in [lo, hi]."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            and lo <= value <= hi)


__all__ = ["AMP_RANGE_RAD", "B_P_RANGE_M", "DIAMETER_RANGE_M", "FREQ_RANGE_HZ", "KNOWN_B_P_RANGE_M", "MASS_RANGE_KG",
           "MAX_PROBES_RANGE", "PAPER_SETUP", "SEED_RANGE", "PaperSetup", "in_range"]
