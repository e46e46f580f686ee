"""Forward models for identification: what a lab's probes are compared against.

A :class:`ForwardModel` is one or more *members*, each the response atlas of one physics model conditioned on what
the lab knows (plate amplitude, B_p, the disc's mass and diameter: :class:`KnownInputs`) with its measured error
against live probes, and a *coherent discrepancy* ``sigma_eps`` (the scale of log omega_n by which the truth may
differ from what the members' curves match) with, across models, an *offset* between the data's model and the
members, estimated by leaving objects or whole models out, never guessed.
:mod:`plate_env.identify.inference` turns a forward model and probes into a posterior.

Shipped forward models (``plate_env/data/forward_models.json``, written by ``experiments/forward_models.py``):
``"<physics>/<model>"`` for data known to come from that simulator, and ``"lab"`` for data of unknown origin (every
physics, the nuisances the paper does not give integrated over, the cross-model discrepancy).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from plate_env.surrogate.atlas import Atlas
from plate_env.surrogate.catalog import read_catalog
from plate_env.surrogate.conditioning import BUILD_HINT, KnownInputs, condition

POOLINGS = ("evidence", "fixed")
#: The unknown joint values of the point-mass family's other members (zeta_bending, k_inplane N/m): one encoding of
#: the fact, read by the registry's builder (:mod:`plate_env.build.forward_models`) and by the out-of-range readings
#: (:mod:`plate_env.identify.identifiability`); the nominal member (0.1, 300) is the shipped dense atlas.
POINTMASS_JOINT_MEMBERS: tuple[tuple[float, float], ...] = tuple(
    (zb, ki) for zb in (0.05, 0.1, 0.2) for ki in (100.0, 300.0, 1000.0) if (zb, ki) != (0.1, 300.0))


def pointmass_member_label(zeta_bending: float, k_inplane: float) -> str:
    """The label of a point-mass member's joint values in its atlas file names, e.g. ``"zb0.05_ki100"``
    (``atlas_tilelink_pointmass_zb0.05_ki100.npz`` and its ``_below`` / ``_above`` extensions)."""
    return f"zb{zeta_bending:g}_ki{k_inplane:g}"


#: The posterior grid reaches this many discrepancies (sigma_eps, log omega) beyond the members' omega_n range
#: (normal discrepancy; a Student-t one reaches its 99.5 % quantile, :func:`pad_sigmas`).
PAD_SIGMAS = 3.0
#: ... but never more than this in log omega (a factor 1000) beyond it: a discrepancy so wide that its 99.5 % quantile
#: lies further (a Cauchy one across models) loses the mass beyond it, so its 95 % interval may end at the grid's
#: end: read such an interval as "at least this wide".
PAD_MAX_LOG = math.log(1000.0)


@functools.lru_cache(maxsize=64)
def pad_sigmas(nu: float) -> float:
    """How many discrepancy scales the grid reaches beyond the models' range for a discrepancy with ``nu`` degrees
    of freedom (inf: normal). scipy's ``t.ppf`` computes the quantile once per machine (kept in the disk cache,
    :mod:`plate_env.core.cache`: a fit does not import scipy.stats)."""
    if math.isinf(nu):
        return PAD_SIGMAS
    from plate_env.core.cache import cached_arrays, content_key

    def build() -> dict[str, np.ndarray]:
        from scipy.stats import t

        return {"q": np.array(t.ppf(0.995, nu), dtype=float)}

    q = cached_arrays("t-quantile", content_key("t-quantile", 0.995, float(nu)), build)["q"]
    return max(PAD_SIGMAS, float(q))


def pad_log(sigma: float, nu: float = math.inf, offset_sigma: float = 0.0, offset_nu: float = math.inf) -> float:
    """How far (in log omega_n) the posterior grid reaches beyond the models' range for a discrepancy (``sigma``,
    ``nu``) and an offset between models: :func:`pad_sigmas` scales of each, at most :data:`PAD_MAX_LOG`."""
    return min(pad_sigmas(nu) * sigma + pad_sigmas(offset_nu) * offset_sigma, PAD_MAX_LOG)


@dataclass(frozen=True)
class Member:
    """One physics model's atlas in a forward model.

    Attributes:
        atlas: the response atlas (its ``n_repeats`` sets the instability smoothing).
        sigma_model: deg/s, the atlas's error against live probes beyond its own spread (measured).
        weight: prior weight of this member in the pool (relative).
        blur: sd of log omega_n over which each probe's likelihood is averaged: the atlas resolves omega_n only to
            about its node spacing, so a probe whose outcome changes quickly with omega_n (a steep flank, an
            instability boundary between two nodes) is not trusted to pin it finer than that.
    """

    atlas: Atlas
    sigma_model: float
    weight: float = 1.0
    blur: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.sigma_model) and self.sigma_model >= 0):
            raise ValueError(f"Member sigma_model = {self.sigma_model!r} deg/s must be >= 0")
        if not (math.isfinite(self.weight) and self.weight > 0):
            raise ValueError(f"Member weight = {self.weight!r} must be > 0")
        if not (math.isfinite(self.blur) and 0.0 <= self.blur <= 1.0):
            raise ValueError(f"Member blur = {self.blur!r} must be in [0, 1] (sd of log omega_n)")

    @property
    def label(self) -> str:
        return f"{self.atlas.physics}/{self.atlas.model}"


@dataclass(frozen=True)
class ForwardModel:
    """Members, a coherent discrepancy (scale ``sigma_eps`` of log omega_n, normal or, with finite ``eps_nu``,
    Student-t with ``eps_nu`` degrees of freedom: across models the errors are heavy-tailed), and how members are
    pooled.

    Across models the discrepancy has two levels (:func:`plate_env.identify.inference.family_discrepancy`): an *offset*
    between the data's model and the members (``offset_sigma``, Student-t with ``offset_nu`` degrees of freedom:
    the number of models it was estimated from, less one), the same for every object, and the object-level scatter
    around it (``sigma_eps``, ``eps_nu``); the posterior is smoothed by both in turn (their sum)."""

    name: str
    members: tuple[Member, ...]
    sigma_eps: float = 0.0
    pooling: str = "evidence"
    provenance: dict = field(default_factory=dict, compare=False)
    eps_nu: float = math.inf
    offset_sigma: float = 0.0
    offset_nu: float = math.inf

    def __post_init__(self) -> None:
        if not self.members:
            raise ValueError("a forward model needs at least one member")
        if not (math.isfinite(self.sigma_eps) and 0.0 <= self.sigma_eps <= 2.0):
            raise ValueError(f"sigma_eps = {self.sigma_eps!r} must be in [0, 2] (sd of log omega_n)")
        if self.pooling not in POOLINGS:
            raise ValueError(f"pooling {self.pooling!r}: choose one of {POOLINGS}")
        if not self.eps_nu >= 1.0:
            raise ValueError(f"eps_nu = {self.eps_nu!r} must be >= 1 (inf: a normal discrepancy)")
        if not (math.isfinite(self.offset_sigma) and 0.0 <= self.offset_sigma <= 2.0):
            raise ValueError(f"offset_sigma = {self.offset_sigma!r} must be in [0, 2] (scale of log omega_n)")
        if not self.offset_nu >= 1.0:
            raise ValueError(f"offset_nu = {self.offset_nu!r} must be >= 1 (inf: a normal offset)")

    @property
    def omega_range(self) -> tuple[float, float]:
        """The union of the members' omega_n ranges, rad/s (the posterior grid)."""
        return (min(float(m.atlas.omega_n[0]) for m in self.members),
                max(float(m.atlas.omega_n[-1]) for m in self.members))

    @property
    def identifiable_range(self) -> tuple[float, float]:
        """The omega_n range some member covers (the union), rad/s: outside it the answer is a bound. A member says
        nothing where it does not reach (its prior is uniform over its own range; the evidence weighs it there)."""
        return self.omega_range

    @property
    def alpha_range(self) -> tuple[float, float]:
        return (max(float(m.atlas.alpha[0]) for m in self.members),
                min(float(m.atlas.alpha[-1]) for m in self.members))

    def grid(self, n_omega: int, n_alpha: int) -> tuple[np.ndarray, np.ndarray]:
        """The posterior grid: log-spaced omega_n (rad/s), ``n_omega`` points over :attr:`omega_range` and, at the
        same spacing, :func:`pad_sigmas` scales of the discrepancy and of the offset (together at most
        :data:`PAD_MAX_LOG`) beyond each end (the truth may lie outside the range the models cover by them);
        uniform alpha (rad)."""
        lo, hi = self.omega_range
        a_lo, a_hi = self.alpha_range
        step = math.log(hi / lo) / (n_omega - 1)
        pad = pad_log(self.sigma_eps, self.eps_nu, self.offset_sigma, self.offset_nu)
        k = math.ceil(pad / step - 1e-9) if pad > 0 else 0
        return (np.geomspace(lo * math.exp(-k * step), hi * math.exp(k * step), n_omega + 2 * k),
                np.linspace(a_lo, a_hi, n_alpha))



# ----------------------------------------------------------------------------------------------- shipped models
@functools.lru_cache(maxsize=64)
def _conditioned(files: tuple[str, ...], known: KnownInputs) -> Atlas:
    """:func:`condition` of shipped atlas files, once per process and inputs: an interpolated atlas is a new
    instance, and its interpolators (cached on it) would be rebuilt at every load (~1 s)."""
    from plate_env.surrogate.atlas import load_atlas_file

    return condition([load_atlas_file(f) for f in files], known)


def load_forward_model(name: str, known: KnownInputs | None = None) -> ForwardModel:
    """A shipped forward model conditioned on the lab's known inputs (default: the paper's B_p 3 mm, 13.6 g,
    80 mm). ``name`` is ``"<physics>/<model>"`` (e.g. ``"tilelink/pointmass"``: the model that made the data is
    known, as in simulation) or ``"lab"`` (data of unknown origin).

    A member with no atlas for these inputs is left out and named in the model's ``provenance["left_out"]`` (the
    estimate's member list shows who answered); ValueError, naming what exists, when no member is left."""
    registry = read_catalog()
    if name not in registry:
        raise ValueError(f"no forward model {name!r}; shipped: {sorted(registry)}")
    entry = registry[name]
    known = known or KnownInputs()
    members, left_out = [], []
    for m in entry["members"]:
        try:
            atlas = _conditioned(tuple(m["atlases"]), known)
        except ValueError as exc:
            left_out.append(str(exc))
            continue
        sigma = m.get("sigma_model")
        if sigma is None:  # the atlas's own held-out measurement
            sigma = atlas.provenance["sigma_model_deg_s"]
        members.append(Member(atlas, float(sigma), float(m.get("weight", 1.0)), float(m.get("blur", 0.0))))
    if not members:
        # members of one physics fail for the same reason: each reason once, the hint once
        reasons = dict.fromkeys(r.removesuffix(f"; {BUILD_HINT}") for r in left_out)
        raise ValueError(f"forward model {name!r} has no member for these known inputs: {'; '.join(reasons)}; "
                         f"{BUILD_HINT}")
    return ForwardModel(name=name, members=tuple(members), sigma_eps=float(entry["sigma_eps"]),
                        eps_nu=float(entry.get("eps_nu", math.inf)),
                        offset_sigma=float(entry.get("offset_sigma", 0.0)),
                        offset_nu=float(entry.get("offset_nu", math.inf)),
                        pooling=entry.get("pooling", "evidence"),
                        provenance={**entry.get("provenance", {}), "left_out": left_out})


#: Shipped forward models loaded per (name, known inputs), the latest few kept (objects of varied mass).
_LOADED: dict[tuple[str, KnownInputs], ForwardModel] = {}
_LOADED_MAX = 8


def shipped_model(name: str, known: KnownInputs) -> ForwardModel:
    """:func:`load_forward_model`, loaded once per (name, known inputs) and shared (the latest
    :data:`_LOADED_MAX`): an estimator, an env and the unknown-origin test read the same object, so what is cached
    on it (its extended model, its responses) is computed once."""
    key = (name, known)
    if key not in _LOADED:
        if len(_LOADED) >= _LOADED_MAX:
            _LOADED.clear()
        _LOADED[key] = load_forward_model(name, known)
    return _LOADED[key]
