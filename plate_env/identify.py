"""From probes to omega_n_hat (and alpha_hat) with uncertainty, by the paper's Lorentzian method or the atlas."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from plate_env.calibration import Calibration, get_calibration
from plate_env.fitting import LorentzFit, fit_lorentzian
from plate_env.physics.base import ProbeResult
from plate_env.probes import ProbeTable

METHODS = ("lorentz", "atlas")


@dataclass(frozen=True)
class Estimate:
    """An identification. ``ok`` False means no estimate could be made (``reason`` says why).

    Attributes:
        omega_n: omega_n_hat, rad/s; omega_n_stderr: rad/s; omega_n_ci68 / omega_n_ci95: credible or confidence
            intervals, rad/s.
        alpha: alpha_hat, rad (None when the method gives none); alpha_stderr: rad.
        fits: the per-amplitude Lorentzian fits (lorentz method), keyed by A_p in degrees.
        posterior: the atlas posterior (atlas method).
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
    fits: dict = field(default_factory=dict, compare=False, repr=False)
    posterior: object = field(default=None, compare=False, repr=False)

    def relative_error(self, omega_n_true: float) -> float:
        return abs(self.omega_n - omega_n_true) / omega_n_true if self.ok else math.inf

    def to_dict(self) -> dict:
        d = {"ok": self.ok, "method": self.method, "reason": self.reason, "omega_n_rad_s": self.omega_n,
             "omega_n_stderr_rad_s": self.omega_n_stderr, "omega_n_pi": self.omega_n / math.pi,
             "omega_n_ci68_rad_s": list(self.omega_n_ci68), "omega_n_ci95_rad_s": list(self.omega_n_ci95),
             "alpha_deg": math.degrees(self.alpha) if self.alpha is not None else None,
             "alpha_stderr_deg": math.degrees(self.alpha_stderr), "n_probes": self.n_probes,
             "n_unstable": self.n_unstable}
        d["fits"] = {f"{a:g}": fit.to_dict() for a, fit in self.fits.items()}
        return d


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
    from plate_env.inference import identify_atlas

    return identify_atlas(table, physics, model, **options)
