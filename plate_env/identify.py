"""From probes to omega_n_hat (and alpha_hat) with uncertainty, by the paper's Lorentzian method or the atlas.

Dependencies run one way: this module uses :mod:`plate_env.inference` (the atlas method) and both build the
:class:`~plate_env.estimate.Estimate` of :mod:`plate_env.estimate`, which imports neither.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from plate_env.calibration import Calibration, get_calibration
from plate_env.estimate import Estimate
from plate_env.fitting import LorentzFit, fit_lorentzian
from plate_env.inference import identify_atlas
from plate_env.physics.base import ProbeResult
from plate_env.probes import ProbeTable

METHODS = ("lorentz", "atlas")


def _table(probes: Sequence[ProbeResult] | ProbeTable) -> ProbeTable:
    return probes if isinstance(probes, ProbeTable) else ProbeTable.from_results(list(probes))


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
    reasons = []
    for amp in table.amplitudes():
        sub = table.subset(np.isclose(table.a_p_deg, amp))
        fit = fit_lorentzian(sub.f_p_hz, sub.omega_b_deg_s, sub.stderr_deg_s if np.any(sub.stderr_deg_s > 0) else None,
                             sub.unstable)
        fits[amp] = fit
        if not fit.ok:
            reasons.append(f"A_p={amp:g} deg: {fit.reason}")
            continue
        cal = cals[amp]
        w = cal.omega_n(fit.f0)
        se = cal.omega_n_stderr(fit.f0, fit.f0_stderr)
        alpha = cal.alpha(fit.omega_max, fit.f0)
        parts.append((w, se, alpha, cal.alpha_resid_std))
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
    return Estimate(ok=True, method="lorentz", omega_n=omega, omega_n_stderr=se,
                    omega_n_ci68=(omega - se, omega + se), omega_n_ci95=(omega - 1.96 * se, omega + 1.96 * se),
                    alpha=alpha, alpha_stderr=alpha_se or 0.0, n_probes=len(table), n_unstable=n_un, fits=fits)


def identify(probes: Sequence[ProbeResult] | ProbeTable, method: str = "lorentz", physics: str = "tilelink",
             model: str = "pointmass", **options) -> Estimate:
    """Estimate omega_n (and alpha) from probes at any plate amplitudes.

    ``method="lorentz"``: the paper's Eq. (9) fit per amplitude and Eq. (10) calibration of ``physics``/``model``
    (``physics="paper"`` uses the paper's coefficients). ``method="atlas"``: the posterior over (omega_n, alpha)
    with the response atlas of ``physics``/``model`` as forward model.
    """
    if method not in METHODS:
        raise ValueError(f"unknown identification method {method!r}; choose one of {METHODS}")
    table = _table(probes)
    if method == "lorentz":
        return identify_lorentz(table, physics, model, **options)
    return identify_atlas(table, physics, model, **options)
