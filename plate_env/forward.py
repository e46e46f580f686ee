"""Forward models for identification: what a set of probes is compared against, and the posterior they give.

A :class:`ForwardModel` is one or more *members* (the response atlas of one physics model, conditioned on what
the lab knows: plate amplitude, B_p, the disc's mass and diameter) and a *coherent discrepancy*. The posterior over
(omega_n, alpha) given probes is (all pure functions here):

1. Per member m and grid point (omega_eff, alpha), the probes' likelihood: a stable probe with omega_B = y +- e
   scores ``(1 - p) * StudentT_nu(y; mu, s^2 + e^2 + sigma_model^2)``, an unstable one ``p``, with the atlas's mean
   mu, spread s (placement scatter between repeats) and instability probability p at (f_p, A_p). ``p`` is the
   share of unstable repeats shrunk towards 1/2 by Jeffreys' rule, ``(k + 1/2) / (R + 1)`` for k of R repeats
   (an atlas point with 0 of 3 unstable repeats says p ~ 1/8, not 0). ``sigma_model`` (deg/s) is the member's
   own error against live probes beyond that spread, measured at held-out points.
2. The discrepancy: the object's true omega_n differs from the omega_eff that member's curves match by a factor
   exp(eps), eps ~ Normal(0, sigma_eps^2), the same for all probes of one object (a model's curve is shifted as a
   whole, not probe by probe). So the likelihood over omega_eff is convolved along log omega with that normal,
   never with less than one grid step. ``sigma_eps`` is estimated, never guessed: within the model that built
   the atlas it is the atlas's interpolation error at held-out objects; across models it comes from leaving
   each model out (``experiments/forward_models.py``).
3. The prior is log-uniform in omega_n over each member's atlas range and uniform in alpha; members are combined
   by their evidence (Bayesian model averaging) times their prior weight, or with fixed weights (``pooling``).

Estimates are the posterior median with equal-tailed 68 % and 95 % intervals, so the point estimate always lies
inside its intervals and the reported standard error is half the 68 % interval. A posterior that piles up against
the edge of the identifiable range (the members' common omega_n range) is reported as a bound, not as a value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from plate_env.atlas import Atlas
from plate_env.probes import ProbeTable

#: Degrees of freedom of the Student-t likelihood of a stable probe.
NU = 4.0
#: Posterior grid sizes.
N_OMEGA = 161
N_ALPHA = 31
#: Share of the posterior allowed in an edge zone of the identifiable range before the answer becomes a bound.
EDGE_MASS = 0.05
POOLINGS = ("evidence", "fixed")
#: The log-omega smoothing is at least this many grid steps (a posterior is never narrower than its grid).
STEP_FLOOR = 0.5


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
    """Members, a coherent discrepancy ``sigma_eps`` (sd of log omega_n), and how members are pooled."""

    name: str
    members: tuple[Member, ...]
    sigma_eps: float = 0.0
    pooling: str = "evidence"
    provenance: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        if not self.members:
            raise ValueError("a forward model needs at least one member")
        if not (math.isfinite(self.sigma_eps) and 0.0 <= self.sigma_eps <= 2.0):
            raise ValueError(f"sigma_eps = {self.sigma_eps!r} must be in [0, 2] (sd of log omega_n)")
        if self.pooling not in POOLINGS:
            raise ValueError(f"pooling {self.pooling!r}: choose one of {POOLINGS}")

    @property
    def omega_range(self) -> tuple[float, float]:
        """The union of the members' omega_n ranges, rad/s (the posterior grid)."""
        return (min(float(m.atlas.omega_n[0]) for m in self.members),
                max(float(m.atlas.omega_n[-1]) for m in self.members))

    @property
    def identifiable_range(self) -> tuple[float, float]:
        """The omega_n range every member covers, rad/s: outside it the answer is a bound."""
        return (max(float(m.atlas.omega_n[0]) for m in self.members),
                min(float(m.atlas.omega_n[-1]) for m in self.members))

    @property
    def alpha_range(self) -> tuple[float, float]:
        return (max(float(m.atlas.alpha[0]) for m in self.members),
                min(float(m.atlas.alpha[-1]) for m in self.members))

    def grid(self, n_omega: int = N_OMEGA, n_alpha: int = N_ALPHA) -> tuple[np.ndarray, np.ndarray]:
        """The posterior grid: log-spaced omega_n (rad/s) over :attr:`omega_range`, uniform alpha (rad)."""
        lo, hi = self.omega_range
        a_lo, a_hi = self.alpha_range
        return np.geomspace(lo, hi, n_omega), np.linspace(a_lo, a_hi, n_alpha)

    def with_sigma_eps(self, sigma_eps: float) -> ForwardModel:
        return ForwardModel(self.name, self.members, sigma_eps, self.pooling, self.provenance)


# ----------------------------------------------------------------------------------------------- likelihood
def log_student(resid: np.ndarray, var: np.ndarray, nu: float = NU) -> np.ndarray:
    """Log-density (up to a constant) of a Student-t residual with scale^2 ``var`` and ``nu`` degrees of freedom."""
    return -0.5 * (nu + 1.0) * np.log1p(resid ** 2 / (nu * var)) - 0.5 * np.log(var)


def smoothed_p(p: np.ndarray, n_repeats: int) -> np.ndarray:
    """Jeffreys' estimate of an instability probability from the share ``p`` of ``n_repeats`` repeats."""
    return (p * n_repeats + 0.5) / (n_repeats + 1.0)


@lru_cache(maxsize=64)
def _response(atlas: Atlas, a_p_deg: float, w_key: tuple[float, float, int], a_key: tuple[float, float, int]):
    """The atlas on a posterior grid at one amplitude, as cubic splines along f_p (exact at the atlas nodes).

    Returns ``f_hz -> (mean, spread, p_unstable)``, each (n_omega, n_alpha), and the mask of grid points inside
    the atlas's omega_n and alpha ranges."""
    from scipy.interpolate import CubicSpline

    w = np.geomspace(*w_key[:2], w_key[2])
    a = np.linspace(*a_key[:2], a_key[2])
    ff, ww, aa = np.meshgrid(atlas.f_hz, w, a, indexing="ij")
    mean, spread, pu = atlas.predict(ff, a_p_deg, ww, aa)
    interps = [CubicSpline(atlas.f_hz, arr, axis=0) for arr in (mean, spread, pu)]
    inside = ((w[:, None] >= atlas.omega_n[0] * (1 - 1e-9)) & (w[:, None] <= atlas.omega_n[-1] * (1 + 1e-9))
              & (a[None, :] >= atlas.alpha[0] - 1e-9) & (a[None, :] <= atlas.alpha[-1] + 1e-9))

    def at(f_hz: float):
        m, s, p = (it(float(f_hz)) for it in interps)
        return m, np.maximum(s, 0.0), np.clip(p, 0.0, 1.0)

    return at, inside


def member_domain(member: Member, f_hz: float, a_p_deg: float) -> str | None:
    """Why a probe lies outside what a member's atlas describes (None if inside)."""
    atlas = member.atlas
    if not np.any(np.isclose(atlas.a_p_deg, a_p_deg, atol=1e-6)):
        return f"A_p = {a_p_deg:g} deg is not in {member.label}'s atlas ({[float(x) for x in atlas.a_p_deg]} deg)"
    if not (atlas.f_hz[0] - 1e-9 <= f_hz <= atlas.f_hz[-1] + 1e-9):
        return f"f_p = {f_hz:g} Hz is outside {member.label}'s atlas ({atlas.f_hz[0]:g}-{atlas.f_hz[-1]:g} Hz)"
    return None


def probe_log_likelihood(mu: np.ndarray, spread: np.ndarray, p_unstable: np.ndarray, omega_b: float,
                         stderr: float, unstable: bool, sigma_model: float, n_repeats: int) -> np.ndarray:
    """One probe's log-likelihood on a grid, from the atlas's mean, spread and raw unstable share there."""
    p = smoothed_p(p_unstable, n_repeats)
    if unstable:
        return np.log(p)
    var = spread ** 2 + stderr ** 2 + sigma_model ** 2
    return np.log1p(-p) + log_student(omega_b - mu, var)


def member_response(member: Member, a_p_deg: float, w: np.ndarray, a: np.ndarray):
    """``(f_hz -> (mean, spread, p_unstable)), inside``: a member's atlas on the grid ``w`` x ``a`` at one amplitude
    (cached per atlas and grid) and the mask of grid points its atlas covers."""
    return _response(member.atlas, float(a_p_deg), (float(w[0]), float(w[-1]), len(w)),
                     (float(a[0]), float(a[-1]), len(a)))


def member_coverage(member: Member, w: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The grid points (n_omega, n_alpha) inside a member's atlas ranges."""
    return member_response(member, float(member.atlas.a_p_deg[0]), w, a)[1]


def blurred(ll: np.ndarray, blur_steps: float) -> np.ndarray:
    """A log-likelihood grid (..., n_omega, n_alpha) averaged, as a likelihood, over a normal of ``blur_steps`` grid
    steps along log omega (axis -2)."""
    if blur_steps <= 0:
        return ll
    from scipy.ndimage import gaussian_filter1d

    top = ll.max(axis=(-2, -1), keepdims=True)
    like = gaussian_filter1d(np.exp(ll - top), blur_steps, axis=-2, mode="nearest", truncate=4.0)
    return np.log(np.maximum(like, 1e-300)) + top


def member_log_likelihood(member: Member, table: ProbeTable, w: np.ndarray, a: np.ndarray
                          ) -> tuple[np.ndarray, int]:
    """Sum of the probes' (blurred) log-likelihoods on the grid (n_omega, n_alpha) for one member, and how many
    probes lay outside its domain (left out)."""
    total = np.zeros((len(w), len(a)))
    skipped = 0
    steps = member.blur / math.log(w[1] / w[0])
    for k in range(len(table)):
        f, amp = float(table.f_p_hz[k]), float(table.a_p_deg[k])
        if member_domain(member, f, amp) is not None:
            skipped += 1
            continue
        mu, s, p = member_response(member, amp, w, a)[0](f)
        total += blurred(probe_log_likelihood(mu, s, p, float(table.omega_b_deg_s[k]), float(table.stderr_deg_s[k]),
                                              bool(table.unstable[k]), member.sigma_model, member.atlas.n_repeats),
                         steps)
    return total, skipped


# ----------------------------------------------------------------------------------------------- posterior
@dataclass(frozen=True)
class Marginal:
    """A one-dimensional posterior summary: median, equal-tailed intervals, and half the 68 % width."""

    value: float
    stderr: float
    ci68: tuple[float, float]
    ci95: tuple[float, float]


@dataclass(frozen=True)
class PooledPosterior:
    """The posterior of a forward model on its grid.

    Attributes:
        omega_n: rad/s (log-spaced); alpha: rad; prob: (n_omega, n_alpha), normalised.
        member_weights: posterior weight of each member (same order as the forward model's members).
        skipped: per member, probes outside its domain (left out of its likelihood).
        sigma_conv: the log-omega smoothing applied (the discrepancy, at least one grid step).
        identifiable_range: rad/s.
    """

    omega_n: np.ndarray
    alpha: np.ndarray
    prob: np.ndarray
    member_weights: tuple[float, ...]
    skipped: tuple[int, ...]
    sigma_conv: float
    identifiable_range: tuple[float, float]

    def marginal_omega(self) -> np.ndarray:
        return self.prob.sum(1)

    def marginal_alpha(self) -> np.ndarray:
        return self.prob.sum(0)

    def omega(self) -> Marginal:
        """omega_n (rad/s): quantiles interpolated in log omega."""
        return _marginal(np.log(self.omega_n), self.marginal_omega(), transform=np.exp,
                         floor=(math.log(self.omega_n[1]) - math.log(self.omega_n[0])))

    def alpha_marginal(self) -> Marginal:
        """alpha (rad)."""
        return _marginal(self.alpha, self.marginal_alpha(), transform=lambda x: x,
                         floor=float(self.alpha[1] - self.alpha[0]) if len(self.alpha) > 1 else 0.0)

    def edge(self) -> str | None:
        """"below" / "above" when more than ``EDGE_MASS`` of the posterior lies beyond (or in the outer grid steps
        of) the identifiable range, else None."""
        p = self.marginal_omega()
        lo, hi = self.identifiable_range
        lw = np.log(self.omega_n)
        margin = 2 * self.sigma_conv
        below = float(p[lw <= math.log(lo) + margin].sum())
        above = float(p[lw >= math.log(hi) - margin].sum())
        if below > EDGE_MASS and below >= above:
            return "below"
        if above > EDGE_MASS:
            return "above"
        return None


def _marginal(x: np.ndarray, p: np.ndarray, transform, floor: float) -> Marginal:
    """Median and equal-tailed intervals of a gridded density (quantiles interpolated in ``x``), mapped by
    ``transform``; the 68 % interval is at least one grid step (``floor`` in x) wide."""
    cdf = np.cumsum(p)
    cdf = cdf / cdf[-1]
    # cell-centred cdf: the mass of cell i is spread evenly over [x_i - dx/2, x_i + dx/2]
    mids = np.concatenate([[x[0]], 0.5 * (x[1:] + x[:-1]), [x[-1]]])
    cdf_edges = np.concatenate([[0.0], cdf])

    def q(level: float) -> float:
        return float(np.interp(level, cdf_edges, mids))

    med = q(0.5)
    lo68, hi68 = q(0.16), q(0.84)
    if hi68 - lo68 < floor:
        lo68, hi68 = med - floor / 2, med + floor / 2
    lo95, hi95 = min(q(0.025), lo68), max(q(0.975), hi68)
    t = transform
    return Marginal(value=float(t(med)), stderr=float((t(hi68) - t(lo68)) / 2), ci68=(float(t(lo68)), float(t(hi68))),
                    ci95=(float(t(lo95)), float(t(hi95))))


def _smooth_log_omega(prob: np.ndarray, sigma_steps: float) -> np.ndarray:
    """Convolve along axis 0 (a uniform log-omega grid) with a normal of ``sigma_steps`` grid steps; mass
    pushed beyond the grid is lost (the prior ends there)."""
    from scipy.ndimage import gaussian_filter1d

    return gaussian_filter1d(prob, sigma_steps, axis=0, mode="constant", cval=0.0, truncate=5.0)


def pool(fm: ForwardModel, w: np.ndarray, a: np.ndarray, log_likes: Sequence[np.ndarray],
         skipped: Sequence[int] = ()) -> PooledPosterior:
    """Combine the members' log-likelihood grids into the posterior: each member's prior is uniform over the grid
    points its atlas covers, its likelihood is smoothed along log omega by the discrepancy (at least
    ``STEP_FLOOR`` grid steps), and members are weighted by evidence x prior weight or by prior weight alone."""
    step = math.log(w[1] / w[0])
    sigma = max(fm.sigma_eps, STEP_FLOOR * step)
    parts, log_z = [], []
    for m, ll in zip(fm.members, log_likes, strict=True):
        inside = member_coverage(m, w, a)
        ll = np.where(inside, ll, -np.inf)
        top = float(ll.max())
        like = _smooth_log_omega(np.exp(ll - top), sigma / step)
        mass = float(like.sum())
        parts.append(like / mass if mass > 0 else like)
        log_z.append(top + math.log(max(mass, 1e-300)) - math.log(max(int(inside.sum()), 1)) + math.log(m.weight))
    log_z = np.array(log_z)
    if fm.pooling == "evidence":
        wts = np.exp(log_z - log_z.max())
    else:
        wts = np.array([m.weight for m in fm.members], dtype=float)
    wts = wts / wts.sum()
    prob = sum(wt * part for wt, part in zip(wts, parts, strict=True))
    prob = prob / prob.sum()
    return PooledPosterior(omega_n=w, alpha=a, prob=prob, member_weights=tuple(float(x) for x in wts),
                           skipped=tuple(skipped) or (0,) * len(fm.members), sigma_conv=sigma,
                           identifiable_range=fm.identifiable_range)


def posterior(fm: ForwardModel, table: ProbeTable, n_omega: int = N_OMEGA, n_alpha: int = N_ALPHA
              ) -> PooledPosterior:
    """The posterior of ``fm`` given the probes (the prior alone when there are none). Pure."""
    w, a = fm.grid(n_omega, n_alpha)
    lls, skipped = zip(*(member_log_likelihood(m, table, w, a) for m in fm.members), strict=True)
    return pool(fm, w, a, lls, skipped)


def members_from(atlases: Sequence[Atlas], sigma_model: Sequence[float], weights: Sequence[float] | None = None
                 ) -> tuple[Member, ...]:
    """Members from atlases and their measured model errors (deg/s)."""
    weights = weights or [1.0] * len(atlases)
    return tuple(Member(at, float(s), float(wt)) for at, s, wt in zip(atlases, sigma_model, weights, strict=True))


# ----------------------------------------------------------------------------------------------- known inputs
@dataclass(frozen=True)
class KnownInputs:
    """What a lab knows about its set-up and disc (SI): B_p (m), the disc's mass (kg) and diameter (m).

    A forward model is conditioned on them: its atlases must have been built at this B_p and diameter, and at
    masses that bracket this one (interpolated in log mass between the two nearest)."""

    b_p: float = 0.003
    mass: float = 0.0136
    diameter: float = 0.080

    def __post_init__(self) -> None:
        for name, lo, hi in (("b_p", 1e-4, 0.05), ("mass", 1e-4, 1.0), ("diameter", 0.01, 0.5)):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= abs(value) <= hi):
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
    """The known inputs an atlas was built at (its provenance; the shipped tile-link defaults where absent)."""
    prov = atlas.provenance or {}
    return KnownInputs(b_p=float(prov.get("b_p_mm", 3.0)) * 1e-3, mass=float(prov.get("mass_g", 13.6)) * 1e-3,
                       diameter=float(prov.get("diameter_mm", 80.0)) * 1e-3)


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
                         f"{known.diameter * 1e3:g} mm (built: (B_p mm, diameter mm) {have}); build one with "
                         "experiments/build_atlas.py")
    ok.sort(key=lambda a: atlas_inputs(a).mass)
    masses = np.array([atlas_inputs(a).mass for a in ok])
    for a, m in zip(ok, masses, strict=True):
        if math.isclose(m, known.mass, rel_tol=INPUT_RTOL):
            return a
    if not (masses[0] < known.mass < masses[-1]):
        raise ValueError(f"no {label} atlas covers a mass of {known.mass * 1e3:g} g (built: "
                         f"{[round(m * 1e3, 2) for m in masses]} g); build one at that mass with "
                         "experiments/build_atlas.py")
    j = int(np.searchsorted(masses, known.mass))
    lo, hi = ok[j - 1], ok[j]
    for name in ("f_hz", "a_p_deg", "omega_n", "alpha"):
        if not np.allclose(getattr(lo, name), getattr(hi, name)):
            raise ValueError(f"{label} atlases at {masses[j - 1] * 1e3:g} g and {masses[j] * 1e3:g} g have different "
                             f"{name} grids: cannot interpolate between them")
    t = math.log(known.mass / masses[j - 1]) / math.log(masses[j] / masses[j - 1])
    prov = dict(lo.provenance or {}, mass_g=known.mass * 1e3,
                interpolated=f"log-mass {1 - t:.3f} x {masses[j - 1] * 1e3:g} g + {t:.3f} x {masses[j] * 1e3:g} g")
    return dataclasses.replace(lo, mean=(1 - t) * lo.mean + t * hi.mean,
                               spread=(1 - t) * lo.spread + t * hi.spread,
                               p_unstable=(1 - t) * lo.p_unstable + t * hi.p_unstable,
                               n_repeats=min(lo.n_repeats, hi.n_repeats), provenance=prov)


# ----------------------------------------------------------------------------------------------- shipped models
#: Package data: the shipped forward models (written by experiments/forward_models.py).
REGISTRY_FILE = "forward_models.json"
#: The forward model for data of unknown origin (a lab's): every physics, the cross-model discrepancy.
LAB = "lab"


def _read_registry() -> dict:
    import json
    from importlib import resources

    ref = resources.files("plate_env") / "data" / REGISTRY_FILE
    return json.loads(ref.read_text()) if ref.is_file() else {}


def forward_model_names() -> list[str]:
    """Names of the shipped forward models ("<physics>/<model>" inside one model, ``"lab"`` across models)."""
    return sorted(_read_registry())


def load_forward_model(name: str, known: KnownInputs | None = None) -> ForwardModel:
    """A shipped forward model conditioned on the lab's known inputs (default: the paper's B_p 3 mm, 13.6 g,
    80 mm). ``name`` is ``"<physics>/<model>"`` (e.g. ``"tilelink/pointmass"``: the model that made the data is
    known, as in simulation) or ``"lab"`` (data of unknown origin)."""
    from plate_env.atlas import load_atlas_file

    registry = _read_registry()
    if name not in registry:
        raise ValueError(f"no forward model {name!r}; shipped: {sorted(registry)}")
    entry = registry[name]
    known = known or KnownInputs()
    members = []
    for m in entry["members"]:
        atlases = [load_atlas_file(f) for f in m["atlases"]]
        members.append(Member(condition(atlases, known), float(m["sigma_model"]), float(m.get("weight", 1.0)),
                              float(m.get("blur", 0.0))))
    return ForwardModel(name=name, members=tuple(members), sigma_eps=float(entry["sigma_eps"]),
                        pooling=entry.get("pooling", "evidence"), provenance=entry.get("provenance", {}))


# ----------------------------------------------------------------------------------------------- estimation
def fit_sigma_model(resid: np.ndarray, spread: np.ndarray, stderr: np.ndarray, nu: float = NU) -> float:
    """Maximum-likelihood model error (deg/s) of an atlas from live stable probes at held-out points: residuals
    ``y - mu`` are Student-t with scale^2 ``spread^2 + stderr^2 + sigma^2``. Pure."""
    from scipy.optimize import minimize_scalar

    r = np.asarray(resid, float)
    base = np.asarray(spread, float) ** 2 + np.asarray(stderr, float) ** 2
    if r.size == 0:
        raise ValueError("no held-out residuals to estimate a model error from")

    def nll(log_s: float) -> float:
        return -float(np.sum(log_student(r, base + math.exp(2 * log_s), nu)))

    best = minimize_scalar(nll, bounds=(math.log(1e-3), math.log(1e3)), method="bounded")
    return float(math.exp(best.x))


def fit_sigma_eps(eps: np.ndarray, post_sd: np.ndarray) -> float:
    """Maximum-likelihood coherent discrepancy (sd of log omega_n) from held-out objects: ``eps = log(truth /
    estimate)`` is normal with variance ``post_sd^2 + sigma^2``, ``post_sd`` the posterior's own log-sd. Pure;
    0 when the posteriors already explain the errors."""
    from scipy.optimize import minimize_scalar

    e = np.asarray(eps, float)
    s2 = np.asarray(post_sd, float) ** 2
    if e.size == 0:
        raise ValueError("no held-out objects to estimate a discrepancy from")

    def nll(sig: float) -> float:
        v = s2 + sig ** 2
        return float(np.sum(0.5 * np.log(v) + 0.5 * e ** 2 / v))

    best = minimize_scalar(nll, bounds=(0.0, 2.0), method="bounded")
    return float(best.x) if nll(best.x) < nll(0.0) else 0.0
