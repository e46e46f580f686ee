"""Can the probes tell an object inside a forward model's identifiable range from one outside it? (issue 37 item 1)

A forward model's posterior lives on the omega_n range its atlases cover (1.4-45 pi rad/s for ``tilelink/pointmass``):
its prior puts nothing beyond. A probe set that an object outside that range explains as well as an alias inside it
gets a confident in-range number: coarse_to_fine's 12 probes of a 60 pi object are explained by a 27.4 pi one (the
predictive check passes, p 0.52), and it answered 27.4 pi, 95 % [25.9, 29.1] pi. The edge rule
(:meth:`plate_env.identify.estimate.Posterior.edge`) cannot see this: the alias is far from the edge.

The test: the posterior of the same probes under the model *extended* beyond its range (:func:`extended_model`), the
member's atlas joined by shipped extension atlases of the same physics at omega_n below and above it
(:data:`EXTENSIONS`: 0.22-1.4 and 45-217 pi rad/s on the member's frequencies, amplitudes, friction angles and
repeats, omega_n nodes 1.1-1.2 apart), with a prior log-uniform over the whole extended range
(each extension member weighted by the log-width of its omega_n range relative to the member's). When more than
:data:`plate_env.identify.estimate.EDGE_MASS` of the members' own posterior (before the discrepancy smoothing, as the
edge rule reads it) lies outside the identifiable range, the probes cannot separate the in-range answer from an
out-of-range object: no estimate, with the stated bound on the side the mass lies (``omega_n > q``, q the lower of
the extended and the in-range posteriors' 2.5 % quantiles, or ``<`` the higher of their 97.5 % ones: true whichever
of the two the object follows), or no bound when mass lies on both sides.

Applied where every member of the forward model has an extension for its known inputs and its set-up (backend and
its options, time step and windows): the tile-link point mass (with each of the nine joint/contact values the ``lab``
pool gives it: :func:`plate_env.identify.unknown_origin.family_model`) and the rigid tiles (``rigid_fast``, the
faithful physics; also the ``tilelink/rigid_limit`` model, which reads the same atlas) at 13.6 g, the env's default
disc. Not the ``lab`` pool as one posterior (the sheet has no extension): its members disagree by design (the offset
between physics), and a member's extension explains another physics' in-range disc as its own object beyond the
range (the pool extended refused 13 of 40 rigid discs at 5-30 pi, experiments/results/estimate_contract.md); its
readings go through every physics' statement instead (:mod:`plate_env.identify.unknown_origin`). Nor other masses.

The test runs when alpha piles at the edge of the friction angles too (that answer is no estimate already): an
object beyond the omega_n range then gets the verdict's bound. Measured: experiments/results/estimate_contract.md.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from plate_env.identify.estimate import EDGE_MASS, Posterior
from plate_env.identify.forward import POINTMASS_JOINT_MEMBERS, ForwardModel, Member, pointmass_member_label
from plate_env.surrogate.atlas import Atlas

#: The point mass's other joint/contact values (the ``lab`` pool's members): zeta_bending and k_inplane, as its atlas
#: files name them.
_JOINTS = tuple(pointmass_member_label(zb, ki) for zb, ki in POINTMASS_JOINT_MEMBERS)
#: Extension atlases per member label (``"physics/model"``; a member takes those whose set-up matches its atlas's,
#: :func:`_matches`): the same physics at omega_n outside the member's range (package data, ``plate-env build atlas
#: --grid pointmass_below_m13.6`` / ``pointmass_above_m13.6``; the other joint values ``--grid pointmass_member_below``
#: / ``pointmass_member_above --nuisance zeta_bending=ZB,k_inplane=KI --repeats 2``; the rigid tiles ``--grid
#: faithful_below`` / ``faithful_above``).
EXTENSIONS: dict[str, tuple[str, ...]] = {
    "tilelink/pointmass": ("atlas_tilelink_pointmass_below.npz", "atlas_tilelink_pointmass_above.npz",
                           *(f"atlas_tilelink_pointmass_{j}_{side}.npz" for j in _JOINTS
                             for side in ("below", "above"))),
    "tilelink/rigid_fast": ("atlas_tilelink_rigid_fast_below.npz", "atlas_tilelink_rigid_fast_above.npz")}
#: Relative tolerance when matching an extension's known inputs (B_p, mass, diameter) to the member atlas's.
INPUT_RTOL = 0.02
#: Set-up values an extension shares with its member atlas exactly (provenance keys: s).
_SETUP = ("dt_s", "ramp_s", "settle_s", "measure_s")


def _matches(ext: Atlas, atlas: Atlas) -> bool:
    """``ext`` describes the member atlas's set-up (its known inputs, amplitudes and frequency range) and lies
    outside its omega_n range (touching it at most)."""
    fa, fb = ext.fixed(), atlas.fixed()
    if set(fa) != set(fb) or not all(math.isclose(fa[k], fb[k], rel_tol=INPUT_RTOL) for k in fa):
        return False
    pa, pb = ext.provenance or {}, atlas.provenance or {}
    if str(pa.get("backend")) != str(pb.get("backend")):  # the same model with the same joint and contact values
        return False
    if any(not math.isclose(float(pa.get(k, math.nan)), float(pb.get(k, math.nan)), rel_tol=1e-9) for k in _SETUP):
        return False
    if ext.a_p_deg.shape != atlas.a_p_deg.shape or not np.allclose(ext.a_p_deg, atlas.a_p_deg):
        return False
    if not (np.isclose(ext.f_hz[0], atlas.f_hz[0]) and np.isclose(ext.f_hz[-1], atlas.f_hz[-1])):
        return False
    lo, hi = float(atlas.omega_n[0]), float(atlas.omega_n[-1])
    return ext.omega_n[-1] <= lo * (1 + 1e-6) or ext.omega_n[0] >= hi * (1 - 1e-6)


def _log_width(atlas: Atlas) -> float:
    return math.log(float(atlas.omega_n[-1]) / float(atlas.omega_n[0]))


def member_extensions(member: Member) -> tuple[Member, ...]:
    """The extension members of ``member`` (:data:`EXTENSIONS` whose inputs match its atlas's), each with the
    member's model error and blur and a prior weight ``member.weight`` x its log omega_n width over the member's
    (a log-uniform prior over the joined range). Empty when there is none."""
    from plate_env.surrogate.atlas import load_atlas_file

    out = []
    for name in EXTENSIONS.get(member.label, ()):
        try:
            ext = load_atlas_file(name)  # package data, loaded once per process
        except (FileNotFoundError, ValueError):
            continue
        if _matches(ext, member.atlas):
            out.append(Member(ext, member.sigma_model, member.weight * _log_width(ext) / _log_width(member.atlas),
                              member.blur))
    return tuple(out)


@dataclasses.dataclass(frozen=True)
class ExtendedModel(ForwardModel):
    """A forward model joined by extension members (:func:`extended_model`), whose posterior grid is ``base``'s
    grid continued outward at its step: the in-range members' rows are ``base``'s own nodes, so their responses
    (cached per atlas and grid) are the ones the in-range posterior computed, not a second set on shifted nodes."""

    base: ForwardModel | None = None

    def grid(self, n_omega: int, n_alpha: int) -> tuple[np.ndarray, np.ndarray]:
        """``base.grid(n_omega, n_alpha)`` (``n_omega``: the base's count) continued at its log step to cover
        :attr:`omega_range` with the base's padding beyond it."""
        assert self.base is not None
        w, a = self.base.grid(n_omega, n_alpha)
        step = math.log(w[1] / w[0])
        b_lo, b_hi = self.base.omega_range
        lo, hi = self.omega_range
        k_lo = max(0, math.ceil(math.log(b_lo / lo) / step - 1e-9))
        k_hi = max(0, math.ceil(math.log(hi / b_hi) / step - 1e-9))
        below = w[0] * np.exp(-step * np.arange(k_lo, 0, -1))
        above = w[-1] * np.exp(step * np.arange(1, k_hi + 1))
        return np.concatenate([below, w, above]), a


def extended_model(fm: ForwardModel) -> ForwardModel | None:
    """``fm`` with every member joined by its extensions (:func:`member_extensions`), pooled by evidence, on a grid
    that continues ``fm``'s (:class:`ExtendedModel`); None when some member has none (the test needs the whole model
    beyond its range) or ``fm`` pools with fixed weights."""
    if fm.pooling != "evidence":
        return None
    key = ("extended", id(fm))
    hit = _EXTENDED.get(key)
    if hit is not None and hit[0] is fm:
        return hit[1]
    extra = [member_extensions(m) for m in fm.members]
    wide = None
    if all(extra):
        fields = {f.name: getattr(fm, f.name) for f in dataclasses.fields(ForwardModel)}
        wide = ExtendedModel(**dict(fields, name=f"{fm.name} (extended)",
                                    members=fm.members + tuple(e for ext in extra for e in ext)), base=fm)
    if len(_EXTENDED) >= 32:
        _EXTENDED.clear()
    _EXTENDED[key] = (fm, wide)
    return wide


#: extended_model per forward model (kept with the model: an id is unique only while it lives).
_EXTENDED: dict[tuple, tuple[ForwardModel, ForwardModel | None]] = {}


@dataclasses.dataclass(frozen=True)
class OutsideMass:
    """The extended posterior's verdict: the members' own posterior mass (before the discrepancy) below and above
    the identifiable range ``(lo, hi)`` rad/s, and the bound's numbers, the 2.5 % / 97.5 % quantiles of omega_n
    (rad/s, with the discrepancy; :func:`outside_mass`)."""

    below: float
    above: float
    q025: float
    q975: float
    identifiable_range: tuple[float, float]
    extended_range: tuple[float, float]

    @property
    def side(self) -> str | None:
        """``"below"`` / ``"above"`` when more than :data:`EDGE_MASS` lies beyond that side of the range, ``"both"``
        when beyond both, None when the probes place the object inside it."""
        b, a = self.below > EDGE_MASS, self.above > EDGE_MASS
        return "both" if a and b else "above" if a else "below" if b else None

    def reason(self, omega_n: float, name: str) -> str:
        lo, hi = self.identifiable_range
        e_lo, e_hi = self.extended_range
        rng = f"{lo / math.pi:.3g}-{hi / math.pi:.3g} pi rad/s"
        head = (f"the probes cannot tell omega_n ~ {omega_n / math.pi:.3g} pi rad/s from an object outside the range "
                f"{name!r} can identify ({rng}): under the model extended to {e_lo / math.pi:.3g}-"
                f"{e_hi / math.pi:.3g} pi rad/s, P(omega_n < {lo / math.pi:.3g} pi) = {self.below:.2f}, "
                f"P(omega_n > {hi / math.pi:.3g} pi) = {self.above:.2f} (> {EDGE_MASS:g})")
        side = self.side
        if side == "above":
            return head + f": omega_n > {self.q025:.4g} rad/s ({self.q025 / math.pi:.3g} pi) at 95 %"
        if side == "below":
            return head + f": omega_n < {self.q975:.4g} rad/s ({self.q975 / math.pi:.3g} pi) at 95 %"
        return head + ": no bound either"

    @property
    def bound(self) -> tuple[str, float] | None:
        side = self.side
        return ("above", self.q025) if side == "above" else ("below", self.q975) if side == "below" else None


def outside_mass(post: Posterior, identifiable_range: tuple[float, float],
                 inside_ci95: tuple[float, float] | None = None) -> OutsideMass:
    """:class:`OutsideMass` of an extended posterior for the original model's ``identifiable_range`` (rad/s).
    ``inside_ci95``: the in-range posterior's 95 % interval (rad/s); the bound's quantiles are then the wider of its
    ends and the extended posterior's, so the bound holds whichever of the two the probes' object follows (on live
    tile-link data a 27.7 pi object read 34.8 pi, 95 % interval holding it, while the extended posterior put 0.97
    above 45 pi and its 2.5 % quantile at 38.2 pi: that bound alone would have been false)."""
    p = post.marginal_omega() if post.model_omega is None else post.model_omega
    p = p / p.sum()
    w = post.omega_n
    lo, hi = identifiable_range
    om = post.omega()
    return OutsideMass(below=float(p[w < lo * (1 - 1e-9)].sum()), above=float(p[w > hi * (1 + 1e-9)].sum()),
                       q025=om.ci95[0] if inside_ci95 is None else min(om.ci95[0], inside_ci95[0]),
                       q975=om.ci95[1] if inside_ci95 is None else max(om.ci95[1], inside_ci95[1]),
                       identifiable_range=(float(lo), float(hi)),
                       extended_range=post.identifiable_range)

