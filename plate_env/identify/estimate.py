"""What an identification returns: an :class:`Estimate` of omega_n (and alpha) and, for the model-based method, the
grid :class:`Posterior` it came from. Plain frozen values; both identification methods (:mod:`plate_env.identify`,
:mod:`plate_env.identify.inference`) build them, so they live below both.

Contracts every estimate keeps: the point estimate lies inside its 68 % interval, which lies inside its 95 %
interval; ``omega_n_stderr`` is half the 68 % interval's width; an answer at the edge of what the method can
identify is a bound (``ok`` False, ``bound`` set), never a confident value.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from plate_env.identify.fitting import LorentzFit

#: The identification methods: ``"atlas"``, a forward model's posterior; ``"lorentz"``, the paper's Eqs. 9-10.
METHODS = ("atlas", "lorentz")

#: Share of the posterior allowed in an edge zone of the identifiable range before the answer becomes a bound.
EDGE_MASS = 0.05
#: The alpha edge rule's factor: an end of the friction-angle range holding this many times its prior share piles.
ALPHA_PILE = 3.0
#: A sweep whose predictive p-value (:func:`plate_env.inference.predictive_check`) is below this is one the forward
#: model cannot explain: no estimate. Calibrated on honest sweeps from the model itself (the share of them rejected:
#: experiments/predictive_check.py, experiments/results/predictive_check.md).
CHECK_P_MIN = 1e-3


@dataclass(frozen=True)
class Marginal:
    """A one-dimensional posterior summary: the median, equal-tailed 68 % and 95 % intervals, half the 68 % width."""

    value: float
    stderr: float
    ci68: tuple[float, float]
    ci95: tuple[float, float]


def marginal(x: np.ndarray, p: np.ndarray, transform: Callable[[float], float] | None = None,
             floor: float = 0.0) -> Marginal:
    """Median and equal-tailed intervals of a density gridded at ``x`` (each cell's mass spread evenly over the
    cell; quantiles interpolated in ``x``), mapped by ``transform``; the 68 % interval is at least ``floor`` (in x)
    wide. Pure."""
    x = np.asarray(x, dtype=float)
    cdf = np.cumsum(p)
    cdf = np.concatenate([[0.0], cdf / cdf[-1]])
    edges = np.concatenate([[x[0]], 0.5 * (x[1:] + x[:-1]), [x[-1]]])

    def q(level: float) -> float:
        return float(np.interp(level, cdf, edges))

    med = q(0.5)
    lo68, hi68 = q(0.16), q(0.84)
    if hi68 - lo68 < floor:
        lo68, hi68 = max(med - floor / 2, x[0]), min(med + floor / 2, x[-1])
    lo95, hi95 = min(q(0.025), lo68), max(q(0.975), hi68)
    t = transform or (lambda v: v)
    return Marginal(value=float(t(med)), stderr=float((t(hi68) - t(lo68)) / 2),
                    ci68=(float(t(lo68)), float(t(hi68))), ci95=(float(t(lo95)), float(t(hi95))))


@dataclass(frozen=True)
class Posterior:
    """A forward model's normalised posterior on a grid: ``prob[i, j]`` for ``omega_n[i]`` (rad/s, log-spaced) and
    ``alpha[j]`` (rad).

    Attributes:
        members: the forward model's member labels; member_weights: their posterior weights.
        skipped: per member, probes outside its domain (left out of its likelihood).
        sigma_conv: the log-omega smoothing applied (the coherent discrepancy, at least half a grid step, and the
            offset between models, in quadrature).
        identifiable_range: the omega_n range (rad/s) every member covers.
        model_omega: the members' pooled marginal over omega_n before the discrepancy smoothing (what the models
            themselves say; the edge rule reads it), None to use the posterior's own marginal.
    """

    omega_n: np.ndarray
    alpha: np.ndarray
    prob: np.ndarray
    members: tuple[str, ...] = ()
    member_weights: tuple[float, ...] = ()
    skipped: tuple[int, ...] = ()
    sigma_conv: float = 0.0
    identifiable_range: tuple[float, float] = (0.0, math.inf)
    model_omega: np.ndarray | None = None

    def marginal_omega(self) -> np.ndarray:
        return np.asarray(self.prob.sum(1))

    def marginal_alpha(self) -> np.ndarray:
        return np.asarray(self.prob.sum(0))

    def omega(self) -> Marginal:
        """omega_n (rad/s): quantiles interpolated in log omega; the 68 % interval at least one grid step wide."""
        lw = np.log(self.omega_n)
        return marginal(lw, self.marginal_omega(), np.exp, floor=float(lw[1] - lw[0]) if lw.size > 1 else 0.0)

    def alpha_marginal(self) -> Marginal:
        """alpha (rad); the 68 % interval at least one grid step wide."""
        return marginal(self.alpha, self.marginal_alpha(),
                        floor=float(self.alpha[1] - self.alpha[0]) if self.alpha.size > 1 else 0.0)

    def edge(self) -> str | None:
        """``"below"`` / ``"above"`` when more than :data:`EDGE_MASS` of the models' own posterior (before the
        discrepancy smoothing, which only widens it) lies beyond the identifiable range or within one grid step of
        its edge, else None: the models would explain the data better outside the range they cover."""
        return self._omega_edge(self.marginal_omega() if self.model_omega is None else self.model_omega)

    def edge_at_inner_alpha(self) -> str | None:
        """The edge rule of :meth:`edge` read on the posterior with alpha held away from the ends of its range (the
        two grid points at each end left out, as :meth:`alpha_edge` counts them): when alpha piles at an end too,
        an omega_n bound holds only if omega_n piles at the same side for the friction angles inside the range, i.e.
        the pile is not bought by the alpha edge. None when fewer than one inner alpha is left or it holds no mass."""
        if self.alpha.size < 5:
            return None
        inner = self.prob[:, 2:-2].sum(1)
        return None if inner.sum() <= 0 else self._omega_edge(inner / inner.sum())

    def _omega_edge(self, p: np.ndarray) -> str | None:
        lw = np.log(self.omega_n)
        lo, hi = self.identifiable_range
        margin = float(lw[1] - lw[0]) if lw.size > 1 else 0.0
        below = float(p[lw <= math.log(lo) + margin].sum())
        above = float(p[lw >= math.log(hi) - margin].sum()) if math.isfinite(hi) else 0.0
        if below > EDGE_MASS and below >= above:
            return "below"
        if above > EDGE_MASS:
            return "above"
        return None

    def alpha_edge(self) -> str | None:
        """``"below"`` / ``"above"`` when the alpha marginal piles against an end of the friction angles the models
        cover (their atlases' range): the two grid points at that end hold more than :data:`EDGE_MASS` and more than
        :data:`ALPHA_PILE` times what the uniform prior puts there, else None. The data would be explained better
        by a friction angle the models do not reach, and their omega_n is then not to be trusted; a posterior that
        leaves alpha undetermined (near the prior) is not flagged."""
        p = self.marginal_alpha()
        n = self.alpha.size
        if n < 4:
            return None
        limit = max(EDGE_MASS, ALPHA_PILE * 2.0 / n)
        below, above = float(p[:2].sum()), float(p[-2:].sum())
        if below > limit and below >= above:
            return "below"
        if above > limit:
            return "above"
        return None


@dataclass(frozen=True)
class PredictiveCheck:
    """How well the forward model's best-fitting object explains the probes (a posterior predictive check).

    ``statistic``: the probes' surprise at the best fit, the sum over stable probes of ``(nu + 1) / 2 *
    log(1 + z^2 / nu)`` (z the residual over the likelihood's own scale, ``sqrt(spread^2 + stderr^2 +
    sigma_model^2)``) plus, over every probe, ``-log P(its stable / unstable flag)``; ``p_value``: the share of
    sweeps replicated from that object (its instability probabilities, Student-t residuals) at least as surprising;
    ``passed``: ``p_value >= CHECK_P_MIN``; ``worst``: the probe explained worst (f_p Hz, A_p deg, z); ``member``: the
    member checked (the one of highest posterior weight)."""

    statistic: float
    p_value: float
    n_probes: int
    member: str
    worst: tuple[float, float, float] | None
    p_min: float = CHECK_P_MIN

    @property
    def passed(self) -> bool:
        return self.p_value >= self.p_min

    def reason(self, forward: str | None = None) -> str:
        """Why the check failed, naming ``forward`` (the forward model that read the probes) and, when it is not
        that model itself, the member checked (its best-fitting one)."""
        where = "" if self.worst is None else (f"; worst probe f_p = {self.worst[0]:g} Hz, A_p = {self.worst[1]:g} "
                                               f"deg, {self.worst[2]:+.3g} model scales off")
        if forward is None or forward == self.member:
            who, member = repr(self.member), ""
        else:
            who, member = f"the forward model {forward!r}", f"its best-fitting member {self.member!r}: "
        return (f"the probes are not a sweep {who} can explain ({member}predictive p-value {self.p_value:.2g} < "
                f"{self.p_min:g}{where}): check the data's units, sign and columns, or use a forward model that "
                "describes the object")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PredictiveCheck:
        w = d.get("worst")
        return cls(statistic=d["statistic"], p_value=d["p_value"], n_probes=d["n_probes"], member=d["member"],
                   worst=None if w is None else (w["f_p_hz"], w["a_p_deg"], w["z"]), p_min=d["p_min"])

    def to_dict(self) -> dict[str, Any]:
        return {"statistic": self.statistic, "p_value": self.p_value, "p_min": self.p_min, "passed": self.passed,
                "n_probes": self.n_probes, "member": self.member,
                "worst": None if self.worst is None else {"f_p_hz": self.worst[0], "a_p_deg": self.worst[1],
                                                          "z": self.worst[2]}}


@dataclass(frozen=True)
class Estimate:
    """An identification. ``ok`` False means no estimate could be made (``reason`` says why).

    Attributes:
        omega_n: omega_n_hat, rad/s; omega_n_stderr: rad/s (half the 68 % interval); omega_n_ci68 / omega_n_ci95:
            credible or confidence intervals, rad/s.
        alpha: alpha_hat, rad (None when the method gives none); alpha_stderr: rad.
        bound: when the answer lies at the edge of what the method can identify: ``("above", x)`` (omega_n > x
            rad/s at 95 %) or ``("below", x)`` (omega_n < x); ``ok`` is then False.
        beyond: the side of the identifiable range (``"below"``, ``"above"``, ``"both"``) beyond which the probes
            place the object, by the edge rule or the extended-range test, else None (``bound`` is None for both).
        forward: the forward model the model-based method used (its name), else None.
        fits: the per-amplitude Lorentzian fits (lorentz method), keyed by A_p in degrees.
        posterior: the model-based posterior, else None.
        check: the model-based method's posterior predictive check of the probes (None for the Lorentzian method);
            a failed check is no estimate (``ok`` False, ``reason`` says why).
        note: a sentence on what the numbers cannot say by themselves (an interval reaching 0: why), else None.
    """

    ok: bool
    method: str
    reason: str | None = None
    omega_n: float = 0.0
    omega_n_stderr: float = 0.0
    omega_n_ci68: tuple[float, float] = (0.0, 0.0)
    omega_n_ci95: tuple[float, float] = (0.0, 0.0)
    alpha: float | None = None
    alpha_stderr: float = 0.0
    n_probes: int = 0
    n_unstable: int = 0
    bound: tuple[str, float] | None = None
    beyond: str | None = None
    forward: str | None = None
    fits: dict[float, LorentzFit] = field(default_factory=dict, compare=False, repr=False)
    posterior: Posterior | None = field(default=None, compare=False, repr=False)
    check: PredictiveCheck | None = None
    #: why the answer reads as it does where its numbers alone would puzzle (e.g. an interval whose lower end is
    #: cut at 0 rad/s), else None
    note: str | None = None

    def __post_init__(self) -> None:
        if self.ok and not (self.omega_n_ci95[0] <= self.omega_n_ci68[0] <= self.omega_n <= self.omega_n_ci68[1]
                            <= self.omega_n_ci95[1]):
            raise ValueError(f"inconsistent estimate: omega_n {self.omega_n!r} with 68 % interval "
                             f"{self.omega_n_ci68!r} and 95 % interval {self.omega_n_ci95!r}")

    def relative_error(self, omega_n_true: float) -> float:
        """|omega_n_hat - omega_n_true| / omega_n_true; inf when there is no estimate."""
        return abs(self.omega_n - omega_n_true) / omega_n_true if self.ok else math.inf

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary in edge units (the posterior grid is left out)."""
        d = {"ok": self.ok, "method": self.method, "reason": self.reason, "forward": self.forward,
             "omega_n_rad_s": self.omega_n, "omega_n_stderr_rad_s": self.omega_n_stderr,
             "omega_n_pi": self.omega_n / math.pi, "omega_n_ci68_rad_s": list(self.omega_n_ci68),
             "omega_n_ci95_rad_s": list(self.omega_n_ci95),
             "alpha_deg": math.degrees(self.alpha) if self.alpha is not None else None,
             "alpha_stderr_deg": math.degrees(self.alpha_stderr), "n_probes": self.n_probes,
             "n_unstable": self.n_unstable,
             "bound": None if self.bound is None else {"side": self.bound[0], "omega_n_rad_s": self.bound[1]},
             "beyond": self.beyond}
        if self.posterior is not None and self.posterior.members:
            members: dict[str, float] = {}  # members sharing a label (one physics, other joint values) summed
            for label, weight in zip(self.posterior.members, self.posterior.member_weights, strict=True):
                members[label] = members.get(label, 0.0) + weight
            d["members"] = members
        d["fits"] = {f"{a:g}": fit.to_dict() for a, fit in self.fits.items()}
        d["check"] = None if self.check is None else self.check.to_dict()
        d["note"] = self.note
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Estimate:
        """The estimate back from :meth:`to_dict` (its posterior grid and per-amplitude fits are not kept)."""
        bound = d.get("bound")
        alpha = d.get("alpha_deg")
        check = d.get("check")
        return cls(ok=d["ok"], method=d["method"], reason=d["reason"], forward=d.get("forward"),
                   omega_n=d["omega_n_rad_s"], omega_n_stderr=d["omega_n_stderr_rad_s"],
                   omega_n_ci68=tuple(d["omega_n_ci68_rad_s"]), omega_n_ci95=tuple(d["omega_n_ci95_rad_s"]),
                   alpha=None if alpha is None else math.radians(alpha),
                   alpha_stderr=math.radians(d.get("alpha_stderr_deg", 0.0)), n_probes=d.get("n_probes", 0),
                   n_unstable=d.get("n_unstable", 0),
                   bound=None if bound is None else (bound["side"], bound["omega_n_rad_s"]),
                   beyond=d.get("beyond"),
                   check=None if check is None else PredictiveCheck.from_dict(check))
