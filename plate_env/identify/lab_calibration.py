"""Calibrated identification (issue 23): a lab measures K reference discs of known omega_n, then reads unknown
discs through what the references taught. Pure functions and frozen dataclasses; no I/O (the file format is
:mod:`plate_env.lab_calibration_file`).

The forward models disagree by tens of percent in omega_n (``experiments/results/forward_models_lomo.md``), and
nothing inside the project says which is right for a given plate. The references decide, as in the paper (which
measures its references' omega_n independently and builds its Eq. (10) line from them). The model:

1. **Readings.** Each member m of a forward model reads a sweep D as a posterior over its own log omega_n,
   ``p_m(u | D)`` (its atlas, its measured model error, no discrepancy; prior uniform in log omega_n over its range;
   marginal over alpha; never narrower than half a grid step). :func:`member_readings`.
2. **Lab-level unknowns** theta = (m, a, b, sigma), shared by every disc on the lab's plate: which member describes
   the lab, and a map from that member's reading to the truth,
   ``log omega_n = c + a + b (u - c) + sigma * eps``, eps ~ N(0, 1), ``c`` a fixed pivot (the references' mean log
   omega_n). ``b`` is 1 (the shipped choice, by measurement) or, on request and from :data:`SLOPE_MIN_REFS`
   references on, log-uniform over :data:`SLOPE_GRID`. ``a`` is uniform over :data:`OFFSET_GRID`. ``sigma``
   (the scatter no member and no map explains: alpha, the disc's own joint values) has a prior
   :class:`ScatterPrior` *learned across labs* (other sources read through the members), so that K = 1 stays
   honest. m is uniform.
3. **Posterior** over theta from the references' likelihood at their known omega_n (:func:`fit_lab`):
   ``p(theta | refs) ~ p(theta) prod_k int p_m(u | D_k) N(log w_k; c + a + b (u - c), sigma^2) du``.
4. **Prediction** for a new disc (:func:`predict`): the predictive of log omega_n, a mixture over the posterior of
   theta of the member's reading mapped through (a, b) and blurred by sigma; the point is its median, the intervals
   equal-tailed. Computed on a grid (no sampling), so it is deterministic.

What the intervals promise, measured: ``experiments/results/calibration_study.md``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import fftconvolve

from plate_env.core.probe_table import ProbeTable
from plate_env.core.setup import in_range
from plate_env.identify.forward import ForwardModel

#: The offset grid (log omega_n): a map may move a member's reading by up to a factor e^2.5 either way.
OFFSET_GRID = np.round(np.arange(-2.5, 2.5 + 1e-9, 0.02), 6)
#: The slope grid (log-uniform prior) used from :data:`SLOPE_MIN_REFS` references on.
SLOPE_GRID = np.round(np.geomspace(0.25, 4.0, 13), 6)
#: References needed before the slope b is fitted when ``fit_lab(slope=None)`` (below: b = 1). The shipped
#: calibration keeps b = 1 at every K: with 3 and 5 references a fitted slope gave larger errors and wider intervals
#: than the offset alone (experiments/results/calibration_study.md, methods `offset` and `slope`).
SLOPE_MIN_REFS = 3
#: The scatter grid (sd of log omega_n).
SIGMA_GRID = np.round(np.geomspace(0.02, 1.0, 16), 6)
#: The ranges a posterior's values lie in (the grids' ends; log omega_n of 0.01-1e4 rad/s, ObjectSpec's top).
OFFSET_RANGE = (float(OFFSET_GRID[0]), float(OFFSET_GRID[-1]))
SLOPE_RANGE = (float(SLOPE_GRID[0]), float(SLOPE_GRID[-1]))
SIGMA_RANGE = (float(SIGMA_GRID[0]), float(SIGMA_GRID[-1]))
LOG_OMEGA_RANGE = (math.log(0.01), math.log(1e4))
#: Smallest usable reading weight: a member that describes none of a sweep's probes has no reading.
_TINY = 1e-300


@dataclass(frozen=True)
class ScatterPrior:
    """Prior over the lab's scatter sigma (sd of log omega_n) on :data:`SIGMA_GRID`: log-normal, median
    ``median``, sd of log sigma ``log_sd`` (learned across labs; see :func:`learn_scatter_prior`)."""

    median: float
    log_sd: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.median) and 0 < self.median <= 2 and math.isfinite(self.log_sd)
                and 0 < self.log_sd <= 5):
            raise ValueError(f"ScatterPrior(median={self.median!r}, log_sd={self.log_sd!r}): median must be in "
                             "(0, 2], log_sd in (0, 5]")

    def log_weights(self, sigmas: np.ndarray = SIGMA_GRID) -> np.ndarray:
        z = (np.log(sigmas) - math.log(self.median)) / self.log_sd
        lw = -0.5 * z ** 2
        return lw - np.logaddexp.reduce(lw)


@dataclass(frozen=True)
class Readings:
    """The members' readings of one sweep: ``prob`` (n_members, n_grid) on the log omega_n grid ``log_w`` (each
    row sums to 1, or is all zero where the member describes none of the probes) and each member's log evidence
    ``log_z`` (the probes' likelihood averaged over its prior; -inf without a reading)."""

    log_w: np.ndarray
    prob: np.ndarray
    log_z: np.ndarray

    def subset(self, idx: Sequence[int]) -> Readings:
        return Readings(self.log_w, self.prob[list(idx)], self.log_z[list(idx)])

    def pooled(self, groups: Sequence[Sequence[int]]) -> Readings:
        """One reading per group of members: their readings weighted by evidence (Bayesian model averaging, as
        :func:`plate_env.inference.pool`; members of one group describe the same probes)."""
        prob, log_z = [], []
        for g in groups:
            lz = self.log_z[list(g)]
            if not np.isfinite(lz).any():
                prob.append(np.zeros_like(self.log_w))
                log_z.append(-np.inf)
                continue
            wt = np.exp(lz - lz.max())
            prob.append(wt @ self.prob[list(g)] / wt.sum())
            log_z.append(float(lz.max() + math.log(wt.mean())))
        return Readings(self.log_w, np.array(prob), np.array(log_z))

    @property
    def available(self) -> np.ndarray:
        return self.prob.sum(1) > 0.5


def reading_grid(fm: ForwardModel, n_omega: int = 321) -> np.ndarray:
    """The common log omega_n grid of the members' readings: ``n_omega`` points over the members' union range."""
    lo, hi = fm.omega_range
    return np.linspace(math.log(lo), math.log(hi), n_omega)


#: Candidate (c), a shape-only reading: the data's amplitude scaled by each of these factors (log-uniform prior,
#: marginalised), so that the hump's height, where the physics disagree by 13-16 %, no longer decides omega_n.
SHAPE_SCALES = np.round(np.geomspace(1 / 1.5, 1.5, 7), 6)


def member_readings(fm: ForwardModel, table: ProbeTable, n_omega: int = 321, n_alpha: int = 16,
                    amplitude_scales: Sequence[float] | None = None, only: Sequence[int] | None = None) -> Readings:
    """Each member's posterior over log omega_n for the probes ``table`` (see the module docstring, step 1).

    ``amplitude_scales``: read the data as ``omega_B / k`` for each k (equal prior weights) and marginalise k,
    a likelihood of the curve's shape with its amplitude normalised out (:data:`SHAPE_SCALES`); None: as measured.
    ``only``: the indices of the members to read (the others get no reading); None: all."""
    from plate_env.identify.inference import STEP_FLOOR, _smooth_log_omega, member_coverage, member_log_likelihood

    log_w = reading_grid(fm, n_omega)
    w = np.exp(log_w)
    a = np.linspace(*fm.alpha_range, n_alpha)
    scales = [1.0] if amplitude_scales is None else [float(k) for k in amplitude_scales]
    tables = [table if k == 1.0 else ProbeTable.from_arrays(table.f_p_hz, table.a_p_deg, table.omega_b_deg_s / k,
                                                           table.stderr_deg_s / k, table.unstable) for k in scales]
    out = np.zeros((len(fm.members), n_omega))
    log_z = np.full(len(fm.members), -np.inf)
    for i, m in enumerate(fm.members):
        if only is not None and i not in only:
            continue
        lls = []
        for t in tables:
            ll, skipped = member_log_likelihood(m, t, w, a)
            if skipped == len(t):
                break
            lls.append(ll)
        if not lls:
            continue
        ll = np.logaddexp.reduce(np.stack(lls), axis=0) - math.log(len(lls))
        inside = member_coverage(m, w, a)
        ll = np.where(inside, ll, -np.inf)
        top = float(ll.max())
        like = np.exp(ll - top)
        log_z[i] = top + math.log(float(like.sum()) / int(inside.sum()))
        like = _smooth_log_omega(like, STEP_FLOOR) * inside
        p = like.sum(1)
        if p.sum() > 0:
            out[i] = p / p.sum()
    return Readings(log_w, out, log_z)


# ----------------------------------------------------------------------------------------------- the lab model
@dataclass(frozen=True)
class LabPosterior:
    """What K references taught about a lab: the posterior over theta = (member, a, b, sigma), kept as the points
    carrying all but ``keep_mass`` (1e-4) of its mass. ``pivot`` c (log omega_n); ``members`` the members' labels
    (the order of ``member``'s indices); ``n_refs`` the references."""

    members: tuple[str, ...]
    pivot: float
    member: tuple[int, ...]
    a: tuple[float, ...]
    b: tuple[float, ...]
    sigma: tuple[float, ...]
    weight: tuple[float, ...]
    n_refs: int
    ref_range: tuple[float, float]
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        """Every value checked against what :func:`fit_lab` can produce (a hand-edited file's 999th member or
        negative scatter is refused here, naming the field and the allowed range, before any array is sized)."""
        n = len(self.weight)
        if not n or any(len(x) != n for x in (self.member, self.a, self.b, self.sigma)):
            raise ValueError("LabPosterior: member, a, b, sigma and weight must have the same non-zero length")
        n_m = len(self.members)
        bad = [m for m in self.member if isinstance(m, bool) or not isinstance(m, int) or not 0 <= m < n_m]
        if bad:
            raise ValueError(f"LabPosterior member index {bad[0]!r} is outside the allowed range [0, {n_m - 1}] (one "
                             f"of the {n_m} members)")
        for name, values, (lo, hi) in (("a", self.a, OFFSET_RANGE), ("b", self.b, SLOPE_RANGE),
                                       ("sigma", self.sigma, SIGMA_RANGE), ("weight", self.weight, (0.0, 1.0)),
                                       ("pivot", (self.pivot,), LOG_OMEGA_RANGE),
                                       ("ref_range", self.ref_range, LOG_OMEGA_RANGE)):
            bad = [v for v in values if not in_range(v, lo, hi)]
            if bad:
                raise ValueError(f"LabPosterior {name} = {bad[0]!r} is outside the allowed range [{lo:g}, {hi:g}]")
        if len(self.ref_range) != 2 or not self.ref_range[0] <= self.pivot <= self.ref_range[1]:
            raise ValueError(f"LabPosterior ref_range {self.ref_range!r} must be a pair (lo, hi) holding the pivot "
                             f"{self.pivot!r} (the references' mean log omega_n)")
        if isinstance(self.n_refs, bool) or not isinstance(self.n_refs, int) or self.n_refs < 1:
            raise ValueError(f"LabPosterior n_refs = {self.n_refs!r} must be an integer >= 1")
        if not math.isclose(sum(self.weight), 1.0, rel_tol=1e-6):
            raise ValueError(f"LabPosterior weights sum to {sum(self.weight)!r}, not 1")

    def member_weights(self) -> dict[str, float]:
        out = dict.fromkeys(self.members, 0.0)
        for m, wt in zip(self.member, self.weight, strict=True):
            out[self.members[m]] += wt
        return out

    def summary(self) -> dict:
        """Posterior means of a, b, sigma and each member's weight (for reports)."""
        wt = np.array(self.weight)
        return {"member_weights": self.member_weights(), "a_mean": float(wt @ np.array(self.a)),
                "b_mean": float(wt @ np.array(self.b)), "sigma_mean": float(wt @ np.array(self.sigma))}


#: The fine grid on which a reference's likelihood is convolved with the scatter (its step, and the FFT length:
#: a period of 20.5 in log omega_n, beyond the offsets plus seven of the largest scatters).
_FINE = 0.01
_N_FFT = 2048


@functools.lru_cache(maxsize=4)
def _gauss_ft(sigmas: tuple[float, ...]) -> np.ndarray:
    omega = 2 * math.pi * np.fft.rfftfreq(_N_FFT, d=_FINE)
    return np.exp(-0.5 * (np.array(sigmas)[:, None] * omega[None, :]) ** 2)


def _log_mix(prob: np.ndarray, log_w: np.ndarray, y: float, a: np.ndarray, bs: np.ndarray, c: float,
             sigmas: np.ndarray) -> np.ndarray:
    """log int p(u) N(y; c + a + b (u - c), sigma^2) du on (b, a, sigma): (n_b, n_a, n_sigma), by binning
    d = y - c - b (u - c) linearly on a fine grid and convolving it with each scatter's normal (FFT)."""
    keep = prob > 1e-10 * prob.max()
    p, u = prob[keep], log_w[keep]
    x0 = -_N_FFT // 2 * _FINE
    d = (y - c - bs[:, None] * (u - c)[None, :] - x0) / _FINE  # (n_b, n_u) in fine-grid units
    d = np.clip(d, 0, _N_FFT - 2)
    lo = np.floor(d).astype(int)
    frac = d - lo
    binned = np.zeros((bs.size, _N_FFT))
    rows = np.repeat(np.arange(bs.size), u.size)
    np.add.at(binned, (rows, lo.ravel()), (p[None, :] * (1 - frac)).ravel())
    np.add.at(binned, (rows, lo.ravel() + 1), (p[None, :] * frac).ravel())
    dens = np.fft.irfft(np.fft.rfft(binned, axis=1)[:, None, :] * _gauss_ft(tuple(sigmas))[None], n=_N_FFT,
                        axis=2) / _FINE  # (n_b, n_sigma, N)
    ia = np.rint((a - x0) / _FINE).astype(int)
    return np.log(np.maximum(dens[:, :, ia], _TINY)).transpose(0, 2, 1)


def fit_lab(refs: Sequence[Readings], log_truth: Sequence[float], members: Sequence[str], prior: ScatterPrior,
            slope: bool | None = False, keep_mass: float = 1e-4, slope_log_sd: float | None = None) -> LabPosterior:
    """The posterior over the lab-level unknowns from K references (their readings and known log omega_n).

    ``slope``: fit b (True; None: from :data:`SLOPE_MIN_REFS` references on; default False: b = 1); its prior on
    :data:`SLOPE_GRID` is log-uniform, or, with ``slope_log_sd``, normal in log b around 1 with that sd (shrinkage
    toward b = 1). A member that
    cannot read every reference (it describes none of a reference's probes) gets no weight. ValueError without
    references."""
    y = np.asarray(log_truth, dtype=float)
    if len(refs) == 0 or len(refs) != y.size:
        raise ValueError(f"fit_lab needs K >= 1 references with a known omega_n each (got {len(refs)} readings, "
                         f"{y.size} truths)")
    slope = (y.size >= SLOPE_MIN_REFS) if slope is None else slope
    c = float(y.mean())
    bs = SLOPE_GRID if slope else np.array([1.0])
    if slope_log_sd is None or bs.size == 1:
        log_b_prior = np.full(bs.size, -math.log(bs.size))
    else:
        log_b_prior = -0.5 * (np.log(bs) / slope_log_sd) ** 2
        log_b_prior -= np.logaddexp.reduce(log_b_prior)
    lsig = prior.log_weights(SIGMA_GRID)
    n_m = refs[0].prob.shape[0]
    pts, lp_list = [], []
    for m in range(n_m):
        if not all(r.available[m] for r in refs):
            continue
        ll_all = sum(_log_mix(r.prob[m], r.log_w, yk, OFFSET_GRID, bs, c, SIGMA_GRID)
                     for r, yk in zip(refs, y, strict=True))
        ia, isg = np.meshgrid(np.arange(OFFSET_GRID.size), np.arange(SIGMA_GRID.size), indexing="ij")
        for j, b in enumerate(bs):
            lp = ll_all[j] + lsig[None, :] + log_b_prior[j]
            pts.append(np.stack([np.full(ia.size, m), OFFSET_GRID[ia.ravel()], np.full(ia.size, b),
                                 SIGMA_GRID[isg.ravel()]], axis=1))
            lp_list.append(lp.ravel())
    if not pts:
        raise ValueError("no member reads every reference: each needs probes some one member describes")
    pts_a, lp_a = np.concatenate(pts), np.concatenate(lp_list)
    wt = np.exp(lp_a - lp_a.max())
    wt /= wt.sum()
    order = np.argsort(wt)[::-1]
    n_keep = int(np.searchsorted(np.cumsum(wt[order]), 1.0 - keep_mass) + 1)
    sel = order[:n_keep]
    w_sel = wt[sel] / wt[sel].sum()
    return LabPosterior(tuple(members), c, tuple(int(x) for x in pts_a[sel, 0]), tuple(float(x) for x in pts_a[sel, 1]),
                        tuple(float(x) for x in pts_a[sel, 2]), tuple(float(x) for x in pts_a[sel, 3]),
                        tuple(float(x) for x in w_sel), int(y.size), (float(y.min()), float(y.max())))


@dataclass(frozen=True)
class Prediction:
    """The predictive of omega_n for one disc: median and equal-tailed intervals (rad/s); ``ok`` False with a
    ``reason`` when no member the references chose reads the sweep."""

    ok: bool
    omega_n: float = 0.0
    ci68: tuple[float, float] = (0.0, 0.0)
    ci95: tuple[float, float] = (0.0, 0.0)
    reason: str | None = None


#: The predictive's log omega_n grid step, half the offset grid's (its quantiles are read on it, linearly interpolated).
PRED_STEP = 0.01


def _kernels(lab: LabPosterior) -> tuple[float, list[tuple[int, float]], np.ndarray]:
    """The lab's offset-and-scatter kernels: per (member, slope) with weight, the density of t = a + sigma * eps
    under the posterior (weights included, on the :data:`PRED_STEP` grid starting at the returned ``t0``)."""
    member, a, b, s, wt = (np.array(x) for x in (lab.member, lab.a, lab.b, lab.sigma, lab.weight))
    reach = 6 * float(s.max())
    t0 = float(OFFSET_GRID[0]) - reach
    n_t = int(round((OFFSET_GRID[-1] - OFFSET_GRID[0] + 2 * reach) / PRED_STEP)) + 1
    keys, kerns = [], []
    for key in sorted({(int(m), float(bb)) for m, bb in zip(member, b, strict=True)}):
        sel = (member == key[0]) & (b == key[1])
        if wt[sel].sum() < 1e-5:  # a negligible (member, slope): left out of the mixture
            continue
        kern = np.zeros(n_t)
        for ss in np.unique(s[sel]):
            one = sel & (s == ss)
            shifts = np.zeros(n_t)
            np.add.at(shifts, np.rint((a[one] - t0) / PRED_STEP).astype(int), wt[one])
            half = math.ceil(6 * ss / PRED_STEP)
            g = np.exp(-0.5 * (np.arange(-half, half + 1) * PRED_STEP / ss) ** 2)
            kern += fftconvolve(shifts, g / g.sum(), mode="same")
        keys.append(key)
        kerns.append(np.maximum(kern, 0.0))
    return t0, keys, np.array(kerns)


def predictive_density(lab: LabPosterior, reading: Readings) -> tuple[np.ndarray, np.ndarray]:
    """``(log omega_n grid, density)`` of the predictive (see the module docstring, step 4); density all zero when
    no member with posterior weight reads the sweep. log omega_n = z + t: z = c + b (u - c) the member's reading
    mapped by the slope, t = a + sigma * eps the offset and scatter (:func:`_kernels`)."""
    log_w, prob, c = reading.log_w, reading.prob, lab.pivot
    if "kernels" not in lab._cache:
        lab._cache["kernels"] = _kernels(lab)
    t0, keys, kerns = lab._cache["kernels"]
    n_t = kerns.shape[1]
    slopes = np.array([k[1] for k in keys])
    z_lo = c + float(np.minimum(slopes * (log_w[0] - c), slopes * (log_w[-1] - c)).min())
    z_hi = c + float(np.maximum(slopes * (log_w[0] - c), slopes * (log_w[-1] - c)).max())
    n_z = int(math.ceil((z_hi - z_lo) / PRED_STEP)) + 2
    n_y = n_z + n_t - 1
    y = z_lo + t0 + PRED_STEP * np.arange(n_y)
    use = [j for j, (m, _) in enumerate(keys) if reading.available[m]]
    if not use:
        return y, np.zeros_like(y)
    base = np.zeros((len(use), n_z))
    for row, j in enumerate(use):
        m, bb = keys[j]
        p = prob[m]
        keep = p > 1e-10 * p.max()
        np.add.at(base[row], np.rint((c + bb * (log_w[keep] - c) - z_lo) / PRED_STEP).astype(int), p[keep])
    n_fft = 1 << (n_y - 1).bit_length()
    key = ("kernels_ft", n_fft)
    if key not in lab._cache:
        lab._cache[key] = np.fft.rfft(kerns, n=n_fft, axis=1)
    ft = (np.fft.rfft(base, n=n_fft, axis=1) * lab._cache[key][use]).sum(0)
    dens = np.maximum(np.fft.irfft(ft, n=n_fft)[:n_y], 0.0)
    total = dens.sum()
    return y, dens / total if total > 0 else dens


def predict(lab: LabPosterior, reading: Readings) -> Prediction:
    """omega_n of a disc from its members' readings through the lab's posterior (rad/s)."""
    y, dens = predictive_density(lab, reading)
    if dens.sum() <= 0:
        return Prediction(False, reason="no member the references chose reads these probes (they describe none of "
                                        "them): sweep the frequencies the references were swept at")
    cdf = np.cumsum(dens)
    cdf = cdf / cdf[-1]

    def q(level: float) -> float:
        return float(math.exp(np.interp(level, cdf, y)))

    return Prediction(True, q(0.5), (q(0.16), q(0.84)), (q(0.025), q(0.975)))
