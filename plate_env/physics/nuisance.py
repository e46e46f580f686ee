"""What nobody knows about a lab's disc and plate: the priors a forward model integrates over (stated, justified).

The paper publishes omega_n, alpha, the mass and the diameter of its objects and the contact law's coefficients,
but not the joint units' stiffness and damping ("obtained from a slice of cheese, as reported in [13]"), and its
contact coefficients were measured for its own plate and cheese. These are *nuisances*: the identification must
hold whatever their values, so a forward model for lab data integrates over them (and over the placement of the
disc and the model's form). Each prior below is a band around the value the project's models use, with the
reason for its width. All draws come from a passed-down ``numpy.random.Generator``.

===================  =========================  ==============================================================
nuisance             prior                      why
===================  =========================  ==============================================================
k_inplane            log-uniform 100-1000 N/m   compression/tension of a 10 mm link; the chosen 300 N/m is
                                                 E t ~ 300 N/m for a 2 mm sheet of E ~ 150 kPa (soft cheese);
                                                 a factor ~3 either way spans soft to firm slices
zeta_inplane         uniform 0.1-0.4            joint damping ratio; food is heavily damped, 0.2 chosen
zeta_bending         log-uniform 0.05-0.2       first bending mode's damping ratio, 0.1 chosen; a factor 2
                                                 either way (free ring-downs of thin food sheets)
contact k, c         log-uniform x0.5-x2         the paper's coefficients were fitted to its own plate/cheese
v_transition         log-uniform 0.07-0.14 m/s  the paper's 0.1 m/s; x2 took a 33pi disc out of the paper's
                                                 regime entirely (no first hump), so the band is narrower
placement            0.2 mm sd per axis,        a careful robot placement (ProbeSpec.perturbed)
                     uniform yaw
===================  =========================  ==============================================================

The effect of each band on the identification is measured in ``experiments/results/forward_models_sensitivity.md``
(``python experiments/forward_models.py sensitivity``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from plate_env.physics.tilelink.contact import PAPER_CONTACT, ContactLaw
from plate_env.physics.tilelink.pointmass import PointMassConfig


@dataclass(frozen=True)
class Band:
    """A prior band: ``lo``-``hi``, log-uniform or uniform."""

    lo: float
    hi: float
    log: bool = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and 0 < self.lo <= self.hi):
            raise ValueError(f"Band ({self.lo!r}, {self.hi!r}) must satisfy 0 < lo <= hi")

    def draw(self, rng: np.random.Generator) -> float:
        if self.log:
            return float(math.exp(rng.uniform(math.log(self.lo), math.log(self.hi))))
        return float(rng.uniform(self.lo, self.hi))

    def at(self, u: float) -> float:
        """The value at quantile ``u`` in [0, 1]."""
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))


@dataclass(frozen=True)
class Nuisance:
    """One draw of the unknowns of the tile-link models (SI units)."""

    k_inplane: float = PointMassConfig.k_inplane
    zeta_inplane: float = PointMassConfig.zeta_inplane
    zeta_bending: float = PointMassConfig.zeta_bending
    contact_k_scale: float = 1.0
    contact_c_scale: float = 1.0
    v_transition: float = PAPER_CONTACT.v_transition

    def tilelink_options(self, model: str = "pointmass") -> dict:
        """``make_physics("tilelink", model=model, **options)`` options that realise this draw."""
        from plate_env.physics.tilelink.rigid import MODEL_CONFIGS, RigidTileConfig

        contact = ContactLaw(k=PAPER_CONTACT.k * self.contact_k_scale, c=PAPER_CONTACT.c * self.contact_c_scale,
                             v_transition=self.v_transition)
        joints = {"k_inplane": self.k_inplane, "zeta_inplane": self.zeta_inplane, "zeta_bending": self.zeta_bending}
        if model == "pointmass":
            return {"model": model, "config": PointMassConfig(**joints), "contact": contact}
        base = MODEL_CONFIGS.get(model, RigidTileConfig())
        return {"model": model, "rigid_config": replace(base, **joints), "contact": contact}


#: The nominal values (the models' defaults).
NOMINAL = Nuisance()


@dataclass(frozen=True)
class NuisancePrior:
    """The stated prior over :class:`Nuisance` (see the module docstring for the reasons)."""

    k_inplane: Band = Band(100.0, 1000.0)
    zeta_inplane: Band = Band(0.1, 0.4, log=False)
    zeta_bending: Band = Band(0.05, 0.2)
    contact_k_scale: Band = Band(0.5, 2.0)
    contact_c_scale: Band = Band(0.5, 2.0)
    v_transition: Band = Band(0.07, 0.14)

    def draw(self, rng: np.random.Generator) -> Nuisance:
        """One draw (fields in declaration order)."""
        return Nuisance(**{name: getattr(self, name).draw(rng) for name in FIELDS})

    def design(self, n: int, rng: np.random.Generator) -> list[Nuisance]:
        """``n`` draws on a Latin hypercube (each band cut into ``n`` strata, one draw per stratum, shuffled per
        field): a space-filling set for building forward-model members."""
        cols = {}
        for name in FIELDS:
            u = (rng.permutation(n) + rng.random(n)) / n
            cols[name] = [getattr(self, name).at(float(x)) for x in u]
        return [Nuisance(**{name: cols[name][i] for name in FIELDS}) for i in range(n)]


#: The nuisance fields in declaration order (of :class:`Nuisance` and :class:`Prior`).
FIELDS = ("k_inplane", "zeta_inplane", "zeta_bending", "contact_k_scale", "contact_c_scale", "v_transition")

#: The project's stated prior.
PRIOR = NuisancePrior()
