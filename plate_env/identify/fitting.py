"""The paper's Lorentzian fit, Eq. (9): omega_B(f_p) = omega_max / (1 + ((f_p - f0) / b)^2). Pure functions.

Units at this edge: f_p, f0 and b in Hz; omega_B and omega_max in deg/s (as probes report them).

Fit window. In the paper's model omega_B rises to a first hump, dips, and (in our simulations) climbs again at
high f_p while more and more probes end unstable. Only the first hump tracks omega_n (physics-facts note), so the
default window is ``"first_hump"``: stable probes in frequency order up to and including the first one that falls
more than ``drop`` (5 %) below the running maximum, or up to two unstable probes in a row, without the flat base
below ``floor`` (40 %) of the hump's height. ``"all"`` uses every stable probe. ``experiments/calibrate.py``
measures the rules (the R^2 of omega_n on f0 and the sweeps each cannot fit, per window, drop and floor) in
``experiments/results/calibration_tilelink_pointmass.md``; the first hump with floor 0.4 is chosen there. Fits
whose peak lies over ``MAX_PEAK_RATIO`` times above every fitted probe (a narrow Lorentzian's tail fitted to the
foot of a hump) are refused, not returned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

WINDOWS = ("first_hump", "all")
#: A stable probe this far below the running maximum ends the first hump.
DEFAULT_DROP = 0.05
#: This many unstable probes in a row (in frequency order) end the first hump.
UNSTABLE_RUN = 2
#: Probes below this fraction of the hump's maximum are left out of the first-hump window.
DEFAULT_FLOOR = 0.4


def lorentzian(f_hz: np.ndarray | float, omega_max: float, f0: float, b: float) -> np.ndarray | float:
    """Eq. (9): ``omega_max / (1 + ((f - f0)/b)^2)``."""
    return omega_max / (1.0 + ((np.asarray(f_hz) - f0) / b) ** 2)


@dataclass(frozen=True)
class LorentzFit:
    """Result of a Lorentzian fit. ``ok`` False means "cannot fit" and ``reason`` says why; then the numbers are 0.

    ``stderr`` and ``cov`` are for (omega_max [deg/s], f0 [Hz], b [Hz]), scaled by the reduced chi-square as
    lmfit does by default. ``used`` marks the probes in the fit window (input order).
    """

    ok: bool
    reason: str | None
    omega_max: float = 0.0
    f0: float = 0.0
    b: float = 0.0
    stderr: tuple[float, float, float] = (0.0, 0.0, 0.0)
    cov: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)), compare=False, repr=False)
    r2: float = 0.0
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0), compare=False, repr=False)
    n_used: int = 0
    n_unstable: int = 0
    used: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool), compare=False, repr=False)
    sign: float = 1.0
    #: every probe the fit did not use, counted by reason (:func:`left_out_reasons`); with ``n_used`` they add up
    #: to the probes given
    left_out: tuple[tuple[str, int], ...] = ()

    @property
    def f0_stderr(self) -> float:
        return self.stderr[1]

    def predict(self, f_hz: np.ndarray | float) -> np.ndarray | float:
        return self.sign * lorentzian(f_hz, self.omega_max, self.f0, self.b)

    def to_dict(self) -> dict:
        return {"ok": self.ok, "reason": self.reason, "omega_max_deg_s": self.omega_max, "f0_hz": self.f0,
                "b_hz": self.b, "omega_max_stderr_deg_s": self.stderr[0], "f0_stderr_hz": self.stderr[1],
                "b_stderr_hz": self.stderr[2], "r2": self.r2, "n_used": self.n_used, "n_unstable": self.n_unstable,
                "left_out": dict(self.left_out)}


#: An unstable run does not end the first-hump window while omega_B rose by more than this fraction per probe into it.
RISE_STEP = 0.1


#: A drop ends the first hump only if it is also this many noise standard deviations deep.
DROP_SIGNIFICANCE = 3.0
#: An unstable run below this fraction of the highest usable omega_B (anywhere in the sweep) is on the hump's
#: foot and is bridged: slips there say nothing about where the hump ends.
FOOT_FRACTION = 0.5
#: Frequencies closer than this (Hz) count as one frequency (repeated probes).
SAME_FREQ_HZ = 1e-6


def curve_by_frequency(f_hz: np.ndarray, omega: np.ndarray, usable: np.ndarray,
                       stderr: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                                  np.ndarray]:
    """The probes reduced to one point per distinct frequency, in frequency order. Pure.

    Returns ``(freqs, mean, noise, has_usable, group)``: each distinct frequency (Hz), the mean omega_B of its
    usable probes (0 where none), the standard deviation of that mean, whether any probe there was usable, and
    for every input probe the index of its frequency. The noise of a frequency is the largest of: the probes'
    own standard errors over sqrt(n), the scatter between its repeats over sqrt(n), and the curve's roughness (a
    robust scale of the second differences of the means, which is what a smooth hump shows of noise) over sqrt(n).
    """
    f_hz = np.asarray(f_hz, dtype=float)
    omega = np.asarray(omega, dtype=float)
    usable = np.asarray(usable, dtype=bool)
    order = np.argsort(f_hz, kind="stable")
    fs = f_hz[order]
    new = np.ones(fs.size, dtype=bool)
    new[1:] = np.diff(fs) > SAME_FREQ_HZ
    group_sorted = np.cumsum(new) - 1
    group = np.empty(f_hz.size, dtype=int)
    group[order] = group_sorted
    n_g = int(group_sorted[-1]) + 1 if fs.size else 0
    freqs = fs[new]
    count = np.bincount(group, weights=usable.astype(float), minlength=n_g)
    total = np.bincount(group, weights=np.where(usable, omega, 0.0), minlength=n_g)
    has = count > 0
    mean = np.where(has, total / np.maximum(count, 1), 0.0)
    dev2 = np.bincount(group, weights=np.where(usable, (omega - mean[group]) ** 2, 0.0), minlength=n_g)
    scatter = np.sqrt(dev2 / np.maximum(count - 1, 1)) * (count >= 2)
    own = np.zeros(n_g)
    if stderr is not None:
        se = np.where(usable & np.isfinite(stderr), np.asarray(stderr, dtype=float), 0.0)
        own = np.sqrt(np.bincount(group, weights=se ** 2, minlength=n_g) / np.maximum(count, 1))
    rough = 0.0
    m = mean[has]
    if m.size >= 5:
        d2 = m[2:] - 2 * m[1:-1] + m[:-2]
        rough = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
    noise = np.maximum.reduce([own, scatter, np.full(n_g, rough)]) / np.sqrt(np.maximum(count, 1))
    return freqs, mean, noise, has, group


def first_hump_mask(f_hz: np.ndarray, omega: np.ndarray, usable: np.ndarray, drop: float = DEFAULT_DROP,
                    floor: float = DEFAULT_FLOOR, stderr: np.ndarray | None = None) -> np.ndarray:
    """Probes of the first hump. Pure.

    Repeated probes of one frequency are taken together (:func:`curve_by_frequency`); walking up in frequency,
    the hump ends at the first frequency whose mean falls below the running maximum by more than ``drop`` of it
    *and* by more than ``DROP_SIGNIFICANCE`` noise standard deviations (so noise at the foot does not end it;
    that frequency is included, it pins the falling side), or at a run of ``UNSTABLE_RUN`` frequencies with no
    usable probe (the paper: past the peak "the object becomes unstable"), unless omega_B was still rising
    steeply into the run (the last two usable frequencies differ by more than ``RISE_STEP`` of the last: the
    hump's top is still ahead) or the run lies on the hump's foot (the running maximum below ``FOOT_FRACTION`` of
    the sweep's highest usable omega_B); such runs are bridged. Frequencies below ``floor`` times the hump's maximum
    (the flat low-frequency base, which a Lorentzian cannot follow) are left out."""
    f_hz = np.asarray(f_hz, dtype=float)
    usable = np.asarray(usable, dtype=bool)
    mask = np.zeros(len(f_hz), dtype=bool)
    if not usable.any():
        return mask
    freqs, mean, noise, has, group = curve_by_frequency(f_hz, omega, usable, stderr)
    keep = np.zeros(freqs.size, dtype=bool)
    foot = FOOT_FRACTION * float(mean[has].max())
    running = -math.inf
    running_noise = 0.0
    last = prev = math.nan
    bad_run = 0
    for g in range(freqs.size):
        if not has[g]:
            bad_run += 1
            rising = last - prev > RISE_STEP * abs(last)  # False while fewer than two usable frequencies
            if running > -math.inf and bad_run >= UNSTABLE_RUN and not rising and running >= foot:
                break
            continue
        bad_run = 0
        prev, last = last, mean[g]
        keep[g] = True
        fall = running - mean[g]
        if fall > drop * running and fall > DROP_SIGNIFICANCE * math.hypot(noise[g], running_noise):
            break
        if mean[g] > running:
            running, running_noise = mean[g], noise[g]
    if floor > 0 and keep.any():
        keep &= mean >= floor * mean[keep].max()
    mask = keep[group] & usable
    return mask


def left_out_reasons(f_hz: np.ndarray, bad: np.ndarray, usable: np.ndarray, used: np.ndarray,
                     floor: float = DEFAULT_FLOOR) -> tuple[tuple[str, int], ...]:
    """Every probe not in the fit window, counted by why (reasons with no probe left out). Pure.

    unstable (no steady omega_B); not finite (f_p or omega_B); below the first hump (stable probes under ``floor``
    of the hump's height: the flat low-frequency base Eq. (9) cannot follow); past the first hump (after the
    drop or the run of unstable probes that ends it: the second hump the paper leaves out)."""
    f_hz = np.asarray(f_hz, dtype=float)
    outside = usable & ~used
    low = outside & (f_hz < f_hz[used].min()) if used.any() else np.zeros_like(outside)
    counts = (("unstable", int(bad.sum())), ("not finite", int((~bad & ~usable).sum())),
              (f"below the first hump (under {floor:.0%} of its height, the flat base)", int(low.sum())),
              ("past the first hump", int((outside & ~low).sum())))
    return tuple((why, n) for why, n in counts if n)


#: A fit whose peak omega_max exceeds the highest fitted probe by more than this factor has no peak in its data.
MAX_PEAK_RATIO = 10.0


def what_would_help(f_hz: np.ndarray, omega: np.ndarray, usable: np.ndarray) -> str:
    """What probes would let a Lorentzian be fitted, judged from where the stable probes' highest omega_B lies
    (sign-normalised ``omega``). Pure."""
    if not usable.any():
        return "what would help: every probe was unstable; probe lower frequencies or a smaller plate amplitude"
    fu, wu = f_hz[usable], omega[usable]
    k = int(np.argmax(wu))
    lo, hi = float(fu.min()), float(fu.max())
    if np.unique(fu).size < 2:
        return f"what would help: probes at several frequencies around {fu[k]:g} Hz"
    if fu[k] >= hi:
        return (f"what would help: omega_B still rises at {hi:g} Hz, the highest stable probe, so the hump's top "
                f"is above it: probe above {hi:g} Hz (or a larger plate amplitude, which moves the hump down)")
    if fu[k] <= lo:
        return (f"what would help: omega_B falls from the lowest stable probe at {lo:g} Hz: probe below {lo:g} Hz "
                "to catch the hump's rising side")
    step = float(np.median(np.diff(np.unique(fu)))) if np.unique(fu).size > 1 else 1.0
    return (f"what would help: more stable probes around the hump near {fu[k]:g} Hz (e.g. every {step / 2:g} Hz "
            f"from {max(lo, fu[k] - 4 * step):g} to {min(hi, fu[k] + 4 * step):g} Hz)")


def fit_lorentzian(f_hz, omega_deg_s, stderr_deg_s=None, unstable=None, window: str = "first_hump",
                   drop: float = DEFAULT_DROP, floor: float = DEFAULT_FLOOR) -> LorentzFit:
    """Fit Eq. (9) by Levenberg-Marquardt (``scipy.optimize.least_squares(method="lm")``).

    Unstable and non-finite probes are excluded and counted. Positivity of omega_max and b is kept by fitting
    their logarithms; starting values come from the data (highest probe, half-height width). Weighted by
    ``1/stderr`` when standard errors are given (zero or missing ones get the median of the others).
    Returns ``LorentzFit(ok=False, reason=...)`` instead of raising when the data cannot support three parameters.
    """
    import scipy.optimize  # lazily: LorentzFit is imported by light modules (plate_env.identify.estimate, the env)

    if window not in WINDOWS:
        raise ValueError(f"unknown fit window {window!r}; choose one of {WINDOWS}")
    f = np.asarray(f_hz, dtype=float).ravel()
    w = np.asarray(omega_deg_s, dtype=float).ravel()
    if f.shape != w.shape:
        raise ValueError(f"f_p has {f.size} values but omega_B has {w.size}")
    bad = np.zeros(f.size, dtype=bool) if unstable is None else np.asarray(unstable, dtype=bool).ravel()
    if bad.shape != f.shape:
        raise ValueError(f"unstable has {bad.size} flags for {f.size} probes")
    if stderr_deg_s is None:
        se = np.ones_like(f)
        weighted = False
    else:
        se = np.asarray(stderr_deg_s, dtype=float).ravel()
        if se.shape != f.shape:
            raise ValueError(f"stderr has {se.size} values for {f.size} probes")
        weighted = True
    n_unstable = int(bad.sum())
    usable = ~bad & np.isfinite(f) & np.isfinite(w)
    sign = 1.0 if np.sum(w[usable]) >= 0 else -1.0
    wa = sign * w
    used = (first_hump_mask(f, wa, usable, drop, floor, se if weighted else None) if window == "first_hump"
            else usable.copy())

    left_out = left_out_reasons(f, bad, usable, used, floor if window == "first_hump" else 0.0)

    def fail(reason: str) -> LorentzFit:
        return LorentzFit(ok=False, reason=f"{reason}; {what_would_help(f, wa, usable)}", n_used=int(used.sum()),
                          n_unstable=n_unstable, used=used, sign=sign, left_out=left_out)

    n = int(used.sum())
    if n < 4:
        return fail(f"{n} usable probes in the fit window; a 3-parameter fit with uncertainties needs at least 4")
    fu, wu = f[used], wa[used]
    if weighted:
        s = se[used].copy()
        good = np.isfinite(s) & (s > 0)
        fill = float(np.median(s[good])) if good.any() else 1.0
        s[~good] = fill
        s = np.maximum(s, 1e-3 * max(fill, 1e-12))
    else:
        s = np.ones(n)
    span = float(fu.max() - fu.min())
    if span <= 0:
        return fail("all probes share one frequency")
    if wu.max() <= 0 or (wu.max() - wu.min()) <= 1e-9 * max(abs(wu.max()), 1.0):
        return fail("omega_B is flat or not positive: no peak to fit")
    # data-driven start: the highest probe, and the half-height width measured on the data
    k = int(np.argmax(wu))
    f0_start = float(fu[k])
    half = wu >= 0.5 * wu[k]
    width = float(fu[half].max() - fu[half].min()) / 2
    b_start = max(width, span / 4, 0.5)
    starts = [(wu[k], f0_start, b_start), (wu[k] * 1.2, f0_start + span / 4, b_start * 1.5),
              (wu[k] * 1.2, f0_start - span / 4, b_start * 1.5)]

    def resid(p):
        amp, width = np.exp(np.clip([p[0], p[2]], -50.0, 50.0))
        return (amp / (1.0 + ((fu - p[1]) / width) ** 2) - wu) / s

    best = None
    for a0, f00, b0 in starts:
        try:
            sol = scipy.optimize.least_squares(resid, [math.log(a0), f00, math.log(b0)], method="lm",
                                               x_scale=[1.0, max(span, 1.0), 1.0], max_nfev=4000)
        except (ValueError, FloatingPointError, OverflowError):
            continue
        if np.all(np.isfinite(sol.x)) and (best is None or sol.cost < best.cost):
            best = sol
    if best is None:
        return fail("the least-squares fit did not converge")
    omega_max, f0, b = math.exp(min(best.x[0], 50.0)), float(best.x[1]), math.exp(min(best.x[2], 50.0))
    if b > 20 * span or abs(f0 - fu.mean()) > 20 * span:
        return fail(f"no peak: the fit ran away (b = {b:.3g} Hz, f0 = {f0:.3g} Hz over a {span:.3g} Hz window)")
    if omega_max > MAX_PEAK_RATIO * float(wu.max()):
        return fail(f"no peak: the fitted peak ({omega_max:.3g} deg/s) is over {MAX_PEAK_RATIO:g}x the highest probe "
                    f"({float(wu.max()):.3g} deg/s); the window holds only the foot of a hump")
    # covariance in natural parameters from the Jacobian of the weighted residuals
    x = 1.0 + ((fu - f0) / b) ** 2
    jac = np.column_stack([1.0 / x, omega_max * 2 * (fu - f0) / (b * b * x * x),
                           omega_max * 2 * (fu - f0) ** 2 / (b ** 3 * x * x)]) / s[:, None]
    res = (omega_max / x - wu)
    dof = n - 3
    chi2 = float(np.sum((res / s) ** 2))
    try:
        cov = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return fail("singular fit: the data do not constrain all three parameters")
    if dof > 0:
        cov = cov * (chi2 / dof)
    else:
        return fail("no degrees of freedom left for uncertainties")
    errs = np.sqrt(np.clip(np.diag(cov), 0, None))
    if not np.all(np.isfinite(errs)) or not np.all(np.isfinite(cov)):
        return fail("non-finite parameter uncertainties")
    ss_tot = float(np.sum((wu - wu.mean()) ** 2))
    r2 = 1.0 - float(np.sum(res ** 2)) / ss_tot if ss_tot > 0 else 0.0
    if not math.isfinite(r2):
        return fail("non-finite R^2: the data overflow double precision")
    return LorentzFit(ok=True, reason=None, omega_max=omega_max, f0=f0, b=b, stderr=tuple(float(e) for e in errs),
                      cov=cov, r2=r2, residuals=sign * res, n_used=n, n_unstable=n_unstable, used=used, sign=sign,
                      left_out=left_out)


def fit_results(results, window: str = "first_hump", weighted: bool = True, drop: float = DEFAULT_DROP,
                floor: float = DEFAULT_FLOOR) -> LorentzFit:
    """Fit a list of ProbeResults (one plate amplitude)."""
    f = [r.spec.motion.freq_hz for r in results]
    w = [r.omega_b_deg_s for r in results]
    se = [r.stderr_deg_s for r in results] if weighted else None
    return fit_lorentzian(f, w, se, [r.unstable for r in results], window=window, drop=drop, floor=floor)
