"""An atlas conditioned on what a lab knows (:class:`KnownInputs`: B_p, the disc's mass and diameter): the atlas
built at those inputs, or two that bracket the mass interpolated in log mass (:func:`condition`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from plate_env.core.setup import DIAMETER_RANGE_M, KNOWN_B_P_RANGE_M, MASS_RANGE_KG, PAPER_SETUP, in_range
from plate_env.surrogate.atlas import Atlas


@dataclass(frozen=True)
class KnownInputs:
    """What a lab knows about its set-up and disc (SI): B_p (m), the disc's mass (kg) and diameter (m).

    A forward model is conditioned on them: its atlases must have been built at this B_p and diameter, and at
    masses that bracket this one (interpolated in log mass between the two nearest)."""

    b_p: float = PAPER_SETUP.b_p
    mass: float = PAPER_SETUP.mass
    diameter: float = PAPER_SETUP.diameter

    def __post_init__(self) -> None:
        for name, (lo, hi) in (("b_p", KNOWN_B_P_RANGE_M), ("mass", MASS_RANGE_KG), ("diameter", DIAMETER_RANGE_M)):
            value = getattr(self, name)
            if not in_range(abs(value) if name == "b_p" and isinstance(value, (int, float)) else value, lo, hi):
                raise ValueError(f"KnownInputs {name} = {value!r} is outside the allowed range [{lo:g}, {hi:g}] (SI)")

    @classmethod
    def from_specs(cls, specs) -> KnownInputs:
        """The common known inputs of some ProbeSpecs (ValueError if they differ)."""
        specs = list(specs)
        if not specs:
            return cls()
        vals = {(abs(s.motion.b_p), s.obj.mass, s.obj.diameter) for s in specs}
        if len(vals) > 1:
            raise ValueError(f"the probes mix set-ups (B_p m, mass kg, diameter m): {sorted(vals)[:4]}; identify "
                             "one disc on one plate at a time")
        b_p, mass, diameter = vals.pop()
        return cls(b_p=b_p, mass=mass, diameter=diameter)


def atlas_inputs(atlas: Atlas) -> KnownInputs:
    """The known inputs an atlas was built at (:meth:`plate_env.surrogate.atlas.Atlas.fixed`)."""
    return KnownInputs(**atlas.fixed())


#: How to make an atlas that is missing (said once per message).
BUILD_HINT = ("build one for these inputs with plate-env build atlas --grid GRID.json (a grid file naming "
              "mass_g, b_p_mm, diameter_mm)")
#: Relative tolerance when matching a lab's B_p, diameter or mass to an atlas's.
INPUT_RTOL = 0.02


def condition(atlases: Sequence[Atlas], known: KnownInputs) -> Atlas:
    """The atlas for ``known`` from atlases of one physics that differ only in the disc's mass: the one at that
    mass, or the two that bracket it interpolated in log mass (mean, spread, instability share). ValueError, naming
    what is available, when B_p or the diameter match none, or the mass lies outside the built masses."""
    import dataclasses

    label = f"{atlases[0].physics}/{atlases[0].model}"
    ins = [atlas_inputs(a) for a in atlases]
    ok = [a for a, k in zip(atlases, ins, strict=True)
          if math.isclose(k.b_p, abs(known.b_p), rel_tol=INPUT_RTOL)
          and math.isclose(k.diameter, known.diameter, rel_tol=INPUT_RTOL)]
    if not ok:
        have = sorted({(round(k.b_p * 1e3, 3), round(k.diameter * 1e3, 1)) for k in ins})
        raise ValueError(f"no {label} atlas for B_p = {abs(known.b_p) * 1e3:g} mm, diameter = "
                         f"{known.diameter * 1e3:g} mm (built: (B_p mm, diameter mm) {have}); {BUILD_HINT}")
    ok.sort(key=lambda a: atlas_inputs(a).mass)
    masses = np.array([atlas_inputs(a).mass for a in ok])
    for a, m in zip(ok, masses, strict=True):
        if math.isclose(m, known.mass, rel_tol=INPUT_RTOL):  # within the tolerance: that atlas answers, and says so
            if m == known.mass:
                return a
            return dataclasses.replace(a, provenance=dict(a.provenance or {}, mass_g=known.mass * 1e3,
                                                          answered_by=f"the {m * 1e3:g} g atlas (within "
                                                                      f"{INPUT_RTOL:.0%})"))
    if not (masses[0] < known.mass < masses[-1]):
        raise ValueError(f"no {label} atlas covers a mass of {known.mass * 1e3:g} g (built: "
                         f"{[float(round(m * 1e3, 2)) for m in masses]} g); {BUILD_HINT}")
    j = int(np.searchsorted(masses, known.mass))
    lo, hi = ok[j - 1], ok[j]
    for name in ("f_hz", "a_p_deg", "alpha"):
        if getattr(lo, name).shape != getattr(hi, name).shape or not np.allclose(getattr(lo, name), getattr(hi, name)):
            raise ValueError(f"{label} atlases at {masses[j - 1] * 1e3:g} g and {masses[j] * 1e3:g} g have different "
                             f"{name} grids: cannot interpolate between them")
    if lo.omega_n.shape != hi.omega_n.shape or not np.allclose(lo.omega_n, hi.omega_n):
        # omega_n nodes may differ (one atlas refined where the response is steep): both on the union of their
        # nodes, each read from its own spline, over the range both cover
        if not (np.isclose(lo.omega_n[0], hi.omega_n[0]) and np.isclose(lo.omega_n[-1], hi.omega_n[-1])):
            raise ValueError(f"{label} atlases at {masses[j - 1] * 1e3:g} g and {masses[j] * 1e3:g} g cover different "
                             "omega_n ranges: cannot interpolate between them")
        union = np.unique(np.round(np.concatenate([lo.omega_n, hi.omega_n]), 9))
        lo, hi = (a if a.omega_n.size == union.size else a.resampled(union) for a in (lo, hi))
    t = math.log(known.mass / masses[j - 1]) / math.log(masses[j] / masses[j - 1])
    prov = dict(lo.provenance or {}, mass_g=known.mass * 1e3,
                interpolated=f"log-mass {1 - t:.3f} x {masses[j - 1] * 1e3:g} g + {t:.3f} x {masses[j] * 1e3:g} g")
    return dataclasses.replace(lo, mean=(1 - t) * lo.mean + t * hi.mean,
                               spread=(1 - t) * lo.spread + t * hi.spread,
                               p_unstable=(1 - t) * lo.p_unstable + t * hi.p_unstable,
                               n_repeats=min(lo.n_repeats, hi.n_repeats), provenance=prov)
