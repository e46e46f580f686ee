"""The paper's Lorentzian method: Eq. (9) fitted per plate amplitude, each f0 mapped through that amplitude's
Eq. (10) line, combined by inverse variance (:func:`identify_lorentz`, read by
:class:`plate_env.identify.estimators.LorentzEstimator`), and the intervals both methods state."""

from __future__ import annotations

import math

import numpy as np

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.calibration import Calibration, get_calibration
from plate_env.identify.estimate import Estimate
from plate_env.identify.fitting import LorentzFit, fit_lorentzian
from plate_env.identify.inference import GAUSS_HERMITE


def positive_intervals(x: float, se: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """The 68 % and 95 % intervals of a normal estimate ``x`` +- ``se`` of a positive quantity (omega_n > 0):
    x -+ se and x -+ 1.96 se, their lower ends cut at 0 (a stiffness is never negative; the cut is the interval's
    statement, not a clamp of the estimate)."""
    return (max(x - se, 0.0), x + se), (max(x - 1.96 * se, 0.0), x + 1.96 * se)


def offset_intervals(x: float, se: float, scale: float, nu: float) -> tuple[tuple[float, float],
                                                                              tuple[float, float], float]:
    """The 68 % and 95 % intervals of ``x`` whose error is normal (sd ``se``) plus a Student-t offset between
    models (``scale``, ``nu`` degrees of freedom), lower ends cut at 0, and the standard error they imply (half the
    68 % width): quantiles of the sum, whose distribution function is the t's averaged over the normal
    (Gauss-Hermite), solved for each probability."""
    if scale <= 0.0 or math.isinf(nu):
        ci68, ci95 = positive_intervals(x, math.hypot(se, scale))
        return ci68, ci95, math.hypot(se, scale)
    from scipy import optimize, stats

    nodes, weights = GAUSS_HERMITE

    def cdf(d: float) -> float:
        return float(np.sum(weights * stats.t.cdf((d - math.sqrt(2.0) * se * nodes) / scale, nu)) / math.sqrt(math.pi))

    hi = stats.t.ppf(0.99, nu) * scale + 6.0 * se
    q68 = optimize.brentq(lambda d: cdf(d) - 0.84, 0.0, hi)
    q95 = optimize.brentq(lambda d: cdf(d) - 0.975, 0.0, hi)
    return (max(x - q68, 0.0), x + q68), (max(x - q95, 0.0), x + q95), q68


def extrapolated_peak(fit: LorentzFit, f_hz: np.ndarray) -> str | None:
    """Why a Lorentzian fit's peak is not read (None when it is): its f0 lies outside the frequencies of the probes
    the fit used, so the hump's top was never probed and f0 is an extrapolation of a rise (or a fall) alone. On the
    point mass such rises cut by instability look alike from 0.5 pi to 50 pi rad/s (issue 37 item 2), so the
    Eq. (10) line would turn noise into a confident omega_n."""
    f_used = np.asarray(f_hz, dtype=float)[fit.used]
    lo, hi = float(f_used.min()), float(f_used.max())
    if lo <= fit.f0 <= hi:
        return None
    side, edge = ("above", hi) if fit.f0 > hi else ("below", lo)
    return (f"the fitted hump's top, f0 = {fit.f0:.1f} Hz, lies {side} the probes the fit used ({lo:g}-{hi:g} Hz): "
            f"an extrapolation, not a measured peak; probe around {fit.f0:.0f} Hz (past {edge:g} Hz) or use the "
            "atlas method")


def identify_lorentz(table: ProbeTable, physics: str = "tilelink", model: str = "pointmass",
                     calibrations: dict[float, Calibration] | None = None) -> Estimate:
    """Fit Eq. (9) per plate amplitude, map each f0 through that amplitude's Eq. (10), combine by inverse variance."""
    n_un = int(table.unstable.sum())
    cals: dict[float, Calibration] = {}
    for amp in table.amplitudes():  # every amplitude calibrated, or no estimate: none is dropped silently
        try:
            cals[amp] = calibrations[amp] if calibrations is not None else get_calibration(physics, model, amp)
        except (KeyError, ValueError) as exc:
            reason = f"A_p = {amp:g} deg: {exc if isinstance(exc, ValueError) else 'no calibration given'}"
            return Estimate(ok=False, method="lorentz", reason=reason, n_probes=len(table), n_unstable=n_un)
    fits: dict[float, LorentzFit] = {}
    parts: list[tuple[float, float, float | None, float]] = []
    offsets: list[tuple[float, float]] = []
    reasons = []
    for amp in table.amplitudes():
        sub = table.subset(np.isclose(table.a_p_deg, amp))
        fit = fit_lorentzian(sub.f_p_hz, sub.omega_b_deg_s, sub.stderr_deg_s if np.any(sub.stderr_deg_s > 0) else None,
                             sub.unstable)
        fits[amp] = fit
        if not fit.ok:
            reasons.append(f"A_p={amp:g} deg: {fit.reason}")
            continue
        if (why := extrapolated_peak(fit, sub.f_p_hz)) is not None:
            reasons.append(f"A_p={amp:g} deg: {why}")
            continue
        cal = cals[amp]
        w = cal.omega_n(fit.f0)
        se = cal.omega_n_stderr(fit.f0, fit.f0_stderr)
        alpha = cal.alpha(fit.omega_max, fit.f0)
        parts.append((w, se, alpha, cal.alpha_resid_std))
        offsets.append((cal.offset_scale(fit.f0), cal.offset_nu))
    if not parts:
        return Estimate(ok=False, method="lorentz", reason="; ".join(reasons) or "no probes", n_probes=len(table),
                        n_unstable=n_un, fits=fits)
    wts = np.array([1.0 / max(se, 1e-9) ** 2 for _, se, _, _ in parts])
    omega = float(np.sum(wts * [p[0] for p in parts]) / wts.sum())
    se = float(1.0 / math.sqrt(wts.sum()))
    alphas = [(a, s) for _, _, a, s in parts if a is not None and s > 0]
    alpha = alpha_se = None
    if alphas:
        aw = np.array([1.0 / s ** 2 for _, s in alphas])
        alpha = float(np.sum(aw * [a for a, _ in alphas]) / aw.sum())
        alpha_se = float(1.0 / math.sqrt(aw.sum()))
    if omega <= 0.0:
        return Estimate(ok=False, method="lorentz", reason=f"the calibration line gives omega_n = {omega:.3g} rad/s "
                        "<= 0 at the fitted f0 (below the line's range): use the atlas method", n_probes=len(table),
                        n_unstable=n_un, fits=fits)
    # the offset between models is one for the object: the amplitudes' offsets averaged with the same weights, the
    # heavier tails kept
    scale = float(np.sum(wts * [o[0] for o in offsets]) / wts.sum())
    ci68, ci95, se = offset_intervals(omega, se, scale, min(o[1] for o in offsets))
    return Estimate(ok=True, method="lorentz", omega_n=omega, omega_n_stderr=se, omega_n_ci68=ci68, omega_n_ci95=ci95,
                    alpha=alpha, alpha_stderr=alpha_se or 0.0, n_probes=len(table), n_unstable=n_un, fits=fits,
                    note=zero_interval_note(omega, ci68, ci95, scale))


def zero_interval_note(omega: float, ci68: tuple[float, float], ci95: tuple[float, float], scale: float) -> str | None:
    """Why a Lorentzian estimate's interval starts at 0 rad/s (None when neither does): the Eq. (10) error is
    additive in rad/s (the fit's, plus the ``scale`` of the offset between the models whose lines were pooled), and
    where the interval's half-width exceeds omega_n_hat its lower end is cut at 0: it then says only omega_n > 0."""
    cut = [(name, ci) for name, ci in (("68 %", ci68), ("95 %", ci95)) if ci[0] <= 0.0]
    if not cut:
        return None
    name, ci = cut[0]
    spread = (f"the pooled physics models' Eq. (10) lines disagree by {scale:.3g} rad/s (offset scale) at this f0"
              if scale > 0 else "the fit and the line are uncertain")
    return (f"the {' and '.join(n for n, _ in cut)} interval{'s start' if len(cut) > 1 else ' starts'} at 0 rad/s: "
            f"{spread}, and the Eq. (10) error is additive in rad/s, so the {name} half-width "
            f"({ci[1] - omega:.3g} rad/s) exceeds omega_n_hat ({omega:.3g} rad/s) and the lower end is cut at 0 (it "
            "says only omega_n > 0). Narrower: the atlas method (fit's default), a lab calibration (plate-env "
            "calibrate), or --physics tilelink --model NAME when the data's physics is known")
