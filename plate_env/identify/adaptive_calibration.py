"""The lab-adaptive calibrated reading (issue 36): two maps from a sweep to omega_n, averaged by what the lab's own
references say about them. Pure functions and frozen dataclasses; no I/O.

1. **The readings map** (:mod:`plate_env.identify.lab_calibration`): member weights + offset + scatter, the scatter
   with a *wide* prior over labs (:data:`SCATTER_PRIOR`), so that the references' own residuals decide it where
   they can.
2. **The feature line**, the paper's way: log omega_n = x . beta + sigma eps with x = (1, f0 - 26 Hz,
   log(omega_Brmax / 600 deg/s)) the Eq. (9) Lorentzian's features of the sweep (:func:`hump_features`); beta and
   sigma shrunk toward a hierarchical prior over labs (:data:`FEATURE_PRIOR`, a :class:`FeatureMixture`: a broad
   prior, the coefficients' spread across the simulated labs of every shipped physics with the scatter log-normal
   and wide, mixed with one component per simulated lab, so that references that line up like one lab select its
   line and scatter). The posterior is computed per component on a scatter grid (conjugate normal per scatter), so
   the predictive is a scale mixture of normals: heavy-tailed, Student-t-like, when the references are few. No
   reading where the Lorentzian fit fails.
3. **The average**: each disc's predictive is ``w F + (1 - w) R`` (CDFs on :data:`LOG_OMEGA_GRID`), ``w`` from the
   references' leave-one-out predictive log scores of the two maps (pseudo-Bayesian model averaging,
   :func:`feature_weight`; 1/2 with one reference); a disc without hump features is read by the readings map alone.

Measured on held-out labs of every shipped physics, each family left out in turn, against the map shipped before:
``experiments/results/calibration_plans.md`` (method ``adaptive``); the priors:
``experiments/results/calibration_plans.json`` (``shipped_priors``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.lab_calibration import (
    PRED_STEP,
    LabPosterior,
    Prediction,
    Readings,
    ScatterPrior,
    fit_lab,
    predictive_density,
)

#: The scatter grid of the feature line (sd of log omega_n).
FEATURE_SIGMAS = np.geomspace(0.02, 1.0, 24)
#: The features' pivots: f0 (Hz) and omega_Brmax (deg/s).
F0_PIVOT_HZ, OMEGA_MAX_PIVOT_DEG_S = 26.0, 600.0
#: log omega_n (rad/s) on which the maps' predictive CDFs are mixed and read: 0.01-1e5 rad/s at a step of 0.0025
#: (wide: a K = 3 predictive is heavy-tailed, and on 1-400 rad/s the 95 % interval's ends of in-range discs were
#: clamped at the grid's).
LOG_OMEGA_GRID = np.linspace(math.log(0.01), math.log(1e5), 6448)

#: The predictive mass beyond either end of LOG_OMEGA_GRID above which no estimate is read: the 95 % interval's tail.
TAIL = 0.025

#: The readings map's scatter prior: median the geometric mean of the in-sample scatters of the simulated labs of
#: every shipped physics (each read through the members of the other families), sd of log sigma 1.5 (wide: the
#: references decide). experiments/results/calibration_plans.json, ``shipped_priors.readings``.
SCATTER_PRIOR = ScatterPrior(median=0.3435, log_sd=1.5)


@dataclass(frozen=True)
class FeaturePrior:
    """The feature line's prior: coefficients normal (``mean``, ``cov``: intercept, per Hz, per unit log peak),
    scatter log-normal (``sigma_median``, sd of log sigma ``log_sd``)."""

    mean: tuple[float, float, float]
    cov: tuple[tuple[float, float, float], ...]
    sigma_median: float
    log_sd: float

    def __post_init__(self) -> None:
        c = np.asarray(self.cov, dtype=float)
        if len(self.mean) != 3 or not np.all(np.isfinite(self.mean)) or c.shape != (3, 3) \
                or not np.all(np.isfinite(c)) or not np.allclose(c, c.T) or np.linalg.eigvalsh(c).min() <= 0:
            raise ValueError("FeaturePrior: mean must be 3 finite numbers, cov a 3 x 3 symmetric positive-definite "
                             "matrix")
        if not (math.isfinite(self.sigma_median) and 0 < self.sigma_median <= 2 and math.isfinite(self.log_sd)
                and 0 < self.log_sd <= 5):
            raise ValueError(f"FeaturePrior(sigma_median={self.sigma_median!r}, log_sd={self.log_sd!r}): "
                             "sigma_median must be in (0, 2], log_sd in (0, 5]")

    def to_json(self) -> dict:
        return {"mean": list(self.mean), "cov": [list(r) for r in self.cov], "sigma_median": self.sigma_median,
                "log_sd": self.log_sd}

    @classmethod
    def from_json(cls, d: dict) -> FeaturePrior:
        return cls(tuple(float(x) for x in d["mean"]), tuple(tuple(float(x) for x in r) for r in d["cov"]),
                   float(d["sigma_median"]), float(d["log_sd"]))


#: The broad component of the shipped feature prior: each simulated lab's least-squares line (every shipped physics:
#: the per-disc and 8 lab-level point-mass labs, rigid_limit, the PyBullet sheet); mean their mean, covariance their
#: spread plus
#: (|mean| + floor)^2 on the diagonal; scatter median the geometric mean of their residual sds.
#: experiments/results/calibration_plans.json, ``shipped_priors.features``.
BROAD_FEATURE_PRIOR = FeaturePrior(
    mean=(4.008862, -0.142085, 5.0804),
    cov=((0.415838, -0.025839, 0.644289), (-0.025839, 0.096409, -0.296014), (0.644289, -0.296014, 41.255364)),
    sigma_median=0.2134, log_sd=1.5)

@dataclass(frozen=True)
class FeatureMixture:
    """A mixture prior over labs for the feature line: each component a :class:`FeaturePrior` (one simulated lab's
    line and scatter, or the broad prior over all of them), ``weights`` the prior probability of each (summing to
    1). The references' marginal likelihood under each component reweights it: references that line up like a
    tight lab select that lab's component (its slopes and scatter), references that do not fall back on the broad
    one. ``labels`` name the components (reports only)."""

    components: tuple[FeaturePrior, ...]
    weights: tuple[float, ...]
    labels: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        w = np.asarray(self.weights, dtype=float)
        if not self.components or w.shape != (len(self.components),) or not np.all(np.isfinite(w)) \
                or np.any(w < 0) or not math.isclose(float(w.sum()), 1.0, abs_tol=1e-6):
            raise ValueError(f"FeatureMixture: {len(self.components)} components need as many weights >= 0 summing "
                             f"to 1, got {self.weights!r}")
        if self.labels and len(self.labels) != len(self.components):
            raise ValueError(f"FeatureMixture: {len(self.labels)} labels for {len(self.components)} components")

    def without(self, labels: Sequence[str]) -> FeatureMixture:
        """The mixture without the components ``labels`` (e.g. a physics family's labs, to measure a lab of that
        family with priors its family never taught), the other weights renormalised. ValueError for a label it
        lacks or when nothing would be left."""
        missing = set(labels) - set(self.labels)
        keep = [i for i, lab in enumerate(self.labels) if lab not in set(labels)]
        if missing or not keep:
            raise ValueError(f"FeatureMixture.without({sorted(labels)}): components are {list(self.labels)}; "
                             "each label must be one of them and at least one must be left")
        total = sum(self.weights[i] for i in keep)
        return FeatureMixture(tuple(self.components[i] for i in keep), tuple(self.weights[i] / total for i in keep),
                              tuple(self.labels[i] for i in keep))

    def to_json(self) -> dict:
        return {"components": [c.to_json() for c in self.components], "weights": list(self.weights),
                "labels": list(self.labels)}

    @classmethod
    def from_json(cls, d: dict) -> FeatureMixture:
        return cls(tuple(FeaturePrior.from_json(c) for c in d["components"]), tuple(float(x) for x in d["weights"]),
                   tuple(str(x) for x in d.get("labels", ())))


def as_mixture(prior: FeaturePrior | FeatureMixture) -> FeatureMixture:
    """A single prior as a one-component mixture."""
    return prior if isinstance(prior, FeatureMixture) else FeatureMixture((prior,), (1.0,))


#: The shipped feature prior (issue 36): a mixture over the simulated labs of every shipped physics (the per-disc
#: and 8 lab-level point-mass labs, rigid_limit, the PyBullet sheet): the broad prior (weight 1/2) and one component
#: per lab (the rest shared equally): its least-squares line, its coefficients' covariance plus a kernel (intercept
#: sd 0.5, slopes 0.05 per Hz and 1.0 per unit log peak), its residual sd the scatter's median (sd of log 0.75).
#: References that line up like one lab select its component. experiments/results/calibration_plans.json,
#: ``shipped_priors.feature_mixture`` (``common.learn_feat_mixture``).
_LAB_COMPONENTS = (  # (lab, mean, cov, sigma_median, log_sd)
    ("pointmass", (4.16224, -0.161539, 6.05456),
     ((0.252204, -0.00054182, 0.0125308),
      (-0.00054182, 0.00304121, -0.0064484),
      (0.0125308, -0.0064484, 1.12153)),
     0.3114, 0.75),
    ("rigid", (3.64853, 0.098811, 3.62471),
     ((0.250952, 0.000676805, -0.0136053),
      (0.000676805, 0.00447397, -0.0301734),
      (-0.0136053, -0.0301734, 1.51347)),
     0.09641, 0.75),
    ("pybullet", (2.9408, -0.155648, 1.36269),
     ((0.287075, 0.00318805, 0.0287498),
      (0.00318805, 0.00299085, 5.17593e-05),
      (0.0287498, 5.17593e-05, 1.05196)),
     0.07615, 0.75),
    ("pmlab500", (4.234, -0.559847, 8.67303),
     ((0.427664, 0.0592492, 0.297742),
      (0.0592492, 0.0953931, -0.522142),
      (0.297742, -0.522142, 6.99153)),
     0.4406, 0.75),
    ("pmlab510", (4.15704, -0.126136, 4.82863),
     ((0.261746, -0.000393273, 0.0417152),
      (-0.000393273, 0.00553006, -0.014669),
      (0.0417152, -0.014669, 1.26347)),
     0.263, 0.75),
    ("pmlab520", (4.03561, -0.0560287, 4.83835),
     ((0.263993, 0.00356565, 0.03307),
      (0.00356565, 0.0157846, -0.0887144),
      (0.03307, -0.0887144, 1.97321)),
     0.3013, 0.75),
    ("pmlab530", (4.33881, -0.156362, 5.58199),
     ((0.284315, -0.00345663, 0.152539),
      (-0.00345663, 0.00462024, -0.0261607),
      (0.152539, -0.0261607, 1.8979)),
     0.3821, 0.75),
    ("pmlab540", (4.10773, -0.190135, 5.4644),
     ((0.260519, -0.00257116, 0.0693887),
      (-0.00257116, 0.0043624, -0.0282723),
      (0.0693887, -0.0282723, 1.74256)),
     0.2617, 0.75),
    ("pmlab550", (4.36981, -0.251577, 5.49813),
     ((0.274249, -0.0045379, 0.124376),
      (-0.0045379, 0.00547995, -0.0408099),
      (0.124376, -0.0408099, 2.00245)),
     0.3936, 0.75),
    ("pmlab560", (3.913, 0.202273, 2.49616),
     ((0.253304, -0.00207604, 0.0387446),
      (-0.00207604, 0.00560811, -0.043482),
      (0.0387446, -0.043482, 1.70044)),
     0.1234, 0.75),
    ("pmlab570", (4.18992, -0.206745, 7.46175),
     ((0.261174, -0.0034524, 0.0741914),
      (-0.0034524, 0.00540967, -0.0413335),
      (0.0741914, -0.0413335, 1.90179)),
     0.3184, 0.75),
)
FEATURE_PRIOR = FeatureMixture(
    (BROAD_FEATURE_PRIOR, *(FeaturePrior(m, c, sg, ls) for _, m, c, sg, ls in _LAB_COMPONENTS)),
    (0.5, *([0.5 / len(_LAB_COMPONENTS)] * len(_LAB_COMPONENTS))),
    ("broad", *(name for name, *_ in _LAB_COMPONENTS)))


Features = tuple[float, float] | None


def hump_features(table: ProbeTable) -> Features:
    """The sweep's Eq. (9) Lorentzian features ``(f0 Hz, omega_Brmax deg/s)``, None where the fit fails."""
    from plate_env.identify.fitting import fit_lorentzian

    fit = fit_lorentzian(table.f_p_hz, table.omega_b_deg_s, table.stderr_deg_s, table.unstable)
    if not fit.ok or not (math.isfinite(fit.f0) and math.isfinite(fit.omega_max) and fit.omega_max > 0):
        return None
    return float(fit.f0), float(fit.omega_max)


def _x(f: tuple[float, float]) -> np.ndarray:
    return np.array([1.0, f[0] - F0_PIVOT_HZ, math.log(f[1] / OMEGA_MAX_PIVOT_DEG_S)])


@dataclass(frozen=True, eq=False)
class FeatureLine:
    """The feature line's posterior on (component, scatter) pairs: per pair its weight, its scatter ``sigma`` and
    the coefficients' normal posterior (``mean`` (n, 3), ``cov`` (n, 3, 3)); ``component`` the posterior weight of
    each mixture component."""

    weight: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    sigma: np.ndarray = field(default_factory=lambda: FEATURE_SIGMAS)
    component: np.ndarray = field(default_factory=lambda: np.ones(1))


def fit_feature_line(prior: FeaturePrior | FeatureMixture, feats: Sequence[Features],
                     log_truth: Sequence[float]) -> FeatureLine:
    """The posterior of the feature line from the references with features (the others are not used; none: the
    prior). A mixture prior: each component's posterior on the scatter grid, weighted by its prior weight times
    the references' marginal likelihood under it."""
    mix = as_mixture(prior)
    use = [i for i, f in enumerate(feats) if f is not None]
    x = np.array([_x(feats[i]) for i in use]).reshape(len(use), 3)
    y = np.asarray(log_truth, dtype=float)[use]
    lps, means, covs, sigmas = [], [], [], []
    for comp, wc in zip(mix.components, mix.weights, strict=True):
        if wc <= 0:
            continue
        m0, c0 = np.asarray(comp.mean), np.asarray(comp.cov)
        lp = math.log(wc) - 0.5 * ((np.log(FEATURE_SIGMAS) - math.log(comp.sigma_median)) / comp.log_sd) ** 2 \
            - math.log(comp.log_sd)
        prec0 = np.linalg.inv(c0)
        r = y - x @ m0
        for j, sg in enumerate(FEATURE_SIGMAS):
            cov_y = sg ** 2 * np.eye(len(y)) + x @ c0 @ x.T
            _, logdet = np.linalg.slogdet(cov_y)
            lp[j] += -0.5 * (logdet + r @ np.linalg.solve(cov_y, r))
            cn = np.linalg.inv(prec0 + x.T @ x / sg ** 2)
            means.append(cn @ (prec0 @ m0 + x.T @ y / sg ** 2))
            covs.append(cn)
        lps.append(lp)
        sigmas.append(FEATURE_SIGMAS)
    lp = np.concatenate(lps)
    wt = np.exp(lp - lp.max())
    wt /= wt.sum()
    comp_w = wt.reshape(len(lps), FEATURE_SIGMAS.size).sum(1)
    return FeatureLine(wt, np.array(means), np.array(covs), np.concatenate(sigmas), comp_w)


def _feature_parts(line: FeatureLine, f: tuple[float, float]):
    x = _x(f)
    keep = line.weight >= 1e-8
    loc = line.mean[keep] @ x
    sd = np.sqrt(line.sigma[keep] ** 2 + np.einsum("i,nij,j->n", x, line.cov[keep], x))
    return line.weight[keep], loc, sd


def feature_cdf(line: FeatureLine, f: Features, grid: np.ndarray = LOG_OMEGA_GRID) -> np.ndarray | None:
    """The feature line's predictive CDF of log omega_n on ``grid`` (None without features)."""
    from scipy.special import ndtr

    if f is None:
        return None
    w, loc, sd = _feature_parts(line, f)
    cdf = (w[:, None] * ndtr((grid[None, :] - loc[:, None]) / sd[:, None])).sum(0)
    return cdf / cdf[-1]


def feature_log_density(line: FeatureLine, f: Features, y: float) -> float | None:
    """The feature line's predictive log density at log omega_n ``y`` (None without features)."""
    if f is None:
        return None
    w, loc, sd = _feature_parts(line, f)
    dens = float(np.sum(w * np.exp(-0.5 * ((y - loc) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))))
    return math.log(max(dens, 1e-300))


def readings_cdf(post: LabPosterior, reading: Readings, grid: np.ndarray = LOG_OMEGA_GRID) -> np.ndarray | None:
    """The readings map's predictive CDF on ``grid`` (None when no member the references chose reads the sweep)."""
    y, dens = predictive_density(post, reading)
    if dens.sum() <= 0:
        return None
    return np.interp(grid, y, np.cumsum(dens) / dens.sum(), left=0.0, right=1.0)


def readings_log_density(post: LabPosterior, reading: Readings, yk: float) -> float | None:
    """The readings map's predictive log density at log omega_n ``yk`` (None without a reading)."""
    y, dens = predictive_density(post, reading)
    if dens.sum() <= 0:
        return None
    return math.log(max(float(np.interp(yk, y, dens)) / PRED_STEP, 1e-300))


def feature_weight(readings: Sequence[Readings], feats: Sequence[Features], log_truth: Sequence[float],
                   members: Sequence[str], scatter_prior: ScatterPrior = SCATTER_PRIOR,
                   feature_prior: FeaturePrior | FeatureMixture = FEATURE_PRIOR) -> float:
    """The feature line's weight in the average: each reference predicted by both maps fitted to the others, the
    log scores summed over the references both read, ``w = 1 / (1 + exp(S_readings - S_features))``; 1/2 with
    fewer than two references or none both read."""
    y = np.asarray(log_truth, dtype=float)
    if y.size < 2:
        return 0.5
    sf = sr = 0.0
    n = 0
    for k in range(y.size):
        rest = [i for i in range(y.size) if i != k]
        lf = feature_log_density(fit_feature_line(feature_prior, [feats[i] for i in rest], y[rest]), feats[k],
                                 float(y[k]))
        try:
            post = fit_lab([readings[i] for i in rest], y[rest], members, scatter_prior)
        except ValueError:  # no member reads every other reference
            continue
        lr = readings_log_density(post, readings[k], float(y[k]))
        if lf is None or lr is None:
            continue
        sf, sr, n = sf + lf, sr + lr, n + 1
    if not n:
        return 0.5
    return 1.0 / (1.0 + math.exp(min(max(sr - sf, -700.0), 700.0)))


def mixed_prediction(f_cdf: np.ndarray | None, r_cdf: np.ndarray | None, w: float,
                     grid: np.ndarray = LOG_OMEGA_GRID) -> Prediction:
    """The average of the two maps' predictives (``w`` the feature line's weight; a map without a reading drops
    out): median and equal-tailed intervals (rad/s). No estimate when more than :data:`TAIL` of it lies beyond
    either end of ``grid`` (the 95 % interval's end would be the grid's, clamped: on a grid of 1-400 rad/s, 100 and
    200 pi point-mass sweeps through the paper's calibration read 1.00 rad/s, 68 % [1.00, 1.13] rad/s)."""
    if f_cdf is None and r_cdf is None:
        return Prediction(False, reason="neither map reads these probes: no member the references chose describes "
                                        "them and their Lorentzian fit fails")
    cdf = r_cdf if f_cdf is None else f_cdf if r_cdf is None else w * f_cdf + (1 - w) * r_cdf
    below, above = float(cdf[0]), float(1.0 - cdf[-1])
    if below > TAIL or above > TAIL:  # the 95 % interval's ends would be clamped at the grid's: not read
        lo, hi = math.exp(grid[0]), math.exp(grid[-1])
        return Prediction(False, reason=(
            f"the calibrated predictive puts {below:.2f} of its mass below {lo:.3g} rad/s ({lo / math.pi:.3g} pi) and "
            f"{above:.2f} above {hi:.3g} rad/s ({hi / math.pi:.3g} pi), the range it is read on (> {TAIL:g}): "
            "the references do not place this disc inside it, so no estimate"))

    def q(level: float) -> float:
        return float(math.exp(np.interp(level, cdf, grid)))

    return Prediction(True, q(0.5), (q(0.16), q(0.84)), (q(0.025), q(0.975)))


@dataclass(frozen=True)
class AdaptiveLab:
    """What K references taught: the readings map's posterior, the feature line's and the feature line's weight."""

    readings: LabPosterior
    line: FeatureLine
    feature_weight: float


def fit_adaptive(readings: Sequence[Readings], feats: Sequence[Features], log_truth: Sequence[float],
                 members: Sequence[str], scatter_prior: ScatterPrior = SCATTER_PRIOR,
                 feature_prior: FeaturePrior | FeatureMixture = FEATURE_PRIOR,
                 weight: float | None = None) -> AdaptiveLab:
    """Both maps fitted to the references and the feature line's weight (:func:`feature_weight`, or ``weight``
    when given: a calibration file's)."""
    post = fit_lab(readings, log_truth, members, scatter_prior)
    line = fit_feature_line(feature_prior, feats, log_truth)
    w = feature_weight(readings, feats, log_truth, members, scatter_prior, feature_prior) if weight is None \
        else float(weight)
    if not 0.0 <= w <= 1.0:
        raise ValueError(f"feature_weight = {w!r} is outside the allowed range [0, 1]")
    return AdaptiveLab(post, line, w)


def predict_adaptive(lab: AdaptiveLab, reading: Readings, f: Features) -> Prediction:
    """omega_n of a disc (rad/s) from its members' readings and its hump features through ``lab``."""
    return mixed_prediction(feature_cdf(lab.line, f), readings_cdf(lab.readings, reading), lab.feature_weight)
