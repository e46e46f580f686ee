"""The object on the plate: a thin disc described by the paper's parameters (SI units)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from plate_env.core.setup import DIAMETER_RANGE_M, MASS_RANGE_KG, PAPER_SETUP, in_range

if TYPE_CHECKING:
    import numpy as np

#: The paper's ratio of kinetic to static friction, mu_k = BETA * mu_s (Section 3.2).
BETA = 0.53


@dataclass(frozen=True)
class ObjectSpec:
    """A thin circular deformable object.

    Attributes:
        omega_n: first-order natural angular frequency in free bending, rad/s.
        alpha: friction angle between plate and object, rad; mu_s = tan(alpha).
        mass: total mass, kg.
        diameter: disc diameter, m.
        beta: mu_k / mu_s (the paper: 0.53).
        name: a label for reports.
    """

    omega_n: float = 10 * math.pi
    alpha: float = math.radians(36.9)
    mass: float = PAPER_SETUP.mass
    diameter: float = PAPER_SETUP.diameter
    beta: float = BETA
    name: str = ""

    def __post_init__(self) -> None:
        checks = {
            "omega_n (rad/s)": (self.omega_n, 0.0, 1e4),
            "alpha (rad)": (self.alpha, 0.0, math.pi / 2),
            "beta": (self.beta, 0.0, 1.0),
        }
        for label, (value, lo, hi) in checks.items():
            if not (isinstance(value, (int, float)) and math.isfinite(value) and lo < value < hi + 1e-12):
                raise ValueError(f"ObjectSpec {label} = {value!r} is outside the allowed range ({lo}, {hi}]")
        for label, value, (lo, hi) in (("mass (kg)", self.mass, MASS_RANGE_KG),
                                       ("diameter (m)", self.diameter, DIAMETER_RANGE_M)):
            if not in_range(value, lo, hi):
                raise ValueError(f"ObjectSpec {label} = {value!r} is outside the allowed range [{lo:g}, {hi:g}] "
                                 "(plate_env.core.setup)")

    @property
    def mu_s(self) -> float:
        """Static friction coefficient, tan(alpha)."""
        return math.tan(self.alpha)

    @property
    def mu_k(self) -> float:
        """Kinetic friction coefficient, beta * mu_s."""
        return self.beta * self.mu_s

    @property
    def radius(self) -> float:
        return self.diameter / 2

    @classmethod
    def from_paper(
        cls, omega_n_pi: float, alpha_deg: float, mass_g: float = PAPER_SETUP.mass_g,
        diameter_mm: float = PAPER_SETUP.diameter_mm, name: str = ""
    ) -> ObjectSpec:
        """Build from the paper's units: omega_n in units of pi rad/s, alpha in degrees, grams, millimetres."""
        return cls(
            omega_n=omega_n_pi * math.pi,
            alpha=math.radians(alpha_deg),
            mass=mass_g * 1e-3,
            diameter=diameter_mm * 1e-3,
            name=name,
        )

    def with_(self, **changes: Any) -> ObjectSpec:
        """A copy with some fields changed."""
        return replace(self, **changes)


#: The paper's objects (Section 6.2). Only the cheese slice has published omega_n and alpha (10pi, 36.9 deg).
#: The dumpling skin "has a similar natural bending frequency" to the cheese: 10pi assumed. The cheese with lead
#: balls has the cheese's stiffness and 39.5/13.6 of its mass: omega_n = 10pi * sqrt(13.6/39.5) ~ 5.87pi assumed.
#: Their friction angles are not published: the cheese's 36.9 deg is assumed for all three.
PRESETS: dict[str, ObjectSpec] = {
    "cheese": ObjectSpec.from_paper(10.0, 36.9, PAPER_SETUP.mass_g, name="cheese"),
    "dumpling": ObjectSpec.from_paper(10.0, 36.9, 6.9, name="dumpling"),
    "cheese_lead": ObjectSpec.from_paper(10.0 * math.sqrt(PAPER_SETUP.mass_g / 39.5), 36.9, 39.5, name="cheese_lead"),
}


@dataclass(frozen=True)
class ObjectPrior:
    """The distribution hidden objects are drawn from (the env's episodes, the agent comparisons).

    Attributes:
        omega_n_range_pi: omega_n is log-uniform over this range, in units of pi rad/s (the paper's 3.5-33).
        alpha_range_deg: alpha is uniform over this range, degrees.
    """

    omega_n_range_pi: tuple[float, float] = (3.5, 33.0)
    alpha_range_deg: tuple[float, float] = (30.0, 60.0)

    def draw(self, rng: np.random.Generator) -> tuple[float, float]:
        """One object's ``(omega_n rad/s, alpha rad)``: exactly two draws from ``rng`` (a numpy Generator),
        omega_n first."""
        lo, hi = self.omega_n_range_pi
        omega_n = math.pi * math.exp(rng.uniform(math.log(lo), math.log(hi)))
        alpha = math.radians(rng.uniform(*self.alpha_range_deg))
        return omega_n, alpha

    def sample(self, n: int, seed: int) -> list[tuple[float, float]]:
        """``n`` objects from a generator seeded with ``seed`` (the same list for the same seed)."""
        import numpy as np

        rng = np.random.default_rng(seed)
        return [self.draw(rng) for _ in range(n)]


def preset(name: str) -> ObjectSpec:
    """Look up a preset object by name (``cheese``, ``dumpling``, ``cheese_lead``)."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown object preset {name!r}; choose one of {sorted(PRESETS)}") from None
