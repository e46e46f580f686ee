"""Model-based inference (beyond the paper): a grid posterior over (omega_n, alpha) with the atlas as forward model.

Likelihood of one probe at (f_p, A_p) for an object (omega_n, alpha), with atlas mean mu, spread s and instability
probability p:
    stable probe with omega_B = y +- e:  (1 - p) * StudentT_4(y; mu, s^2 + e^2 + sigma_model^2)
    unstable probe:                      p
The Student-t (4 degrees of freedom) keeps one probe that the atlas describes badly (e.g. a rare stable probe
in a mostly unstable region) from dominating the posterior, as a Gaussian did.
with p clipped to [P_MIN, 1 - P_MIN] (no single probe can rule an object out on stability alone) and
``sigma_model`` (deg/s) covering the atlas's interpolation error against live probes. The prior is uniform in
log omega_n over the atlas's range and uniform in alpha. Works with any set of probes: mixed amplitudes,
one-sided data, curves without a Lorentzian peak.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from plate_env.atlas import Atlas, load_atlas
from plate_env.estimate import Estimate, Posterior
from plate_env.probes import ProbeTable

#: A function f_p (Hz) -> (mean deg/s, spread deg/s, p_unstable) on the posterior grid, each (n_omega, n_alpha).
GridResponse = Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]

P_MIN = 0.02
#: Degrees of freedom of the Student-t likelihood.
NU = 4.0
#: Default model error of the atlas, deg/s (measured against live probes by experiments/build_atlas.py).
SIGMA_MODEL = 15.0


def posterior_grid(atlas: Atlas, n_omega: int = 161, n_alpha: int = 31) -> tuple[np.ndarray, np.ndarray]:
    """The posterior's grid: log-spaced omega_n and uniform alpha over the atlas's ranges."""
    w = np.geomspace(atlas.omega_n[0], atlas.omega_n[-1], n_omega)
    a = np.linspace(atlas.alpha[0], atlas.alpha[-1], n_alpha)
    return w, a


def log_student(resid: np.ndarray, var: np.ndarray, nu: float = NU) -> np.ndarray:
    """Log-density (up to a constant) of a Student-t residual with scale^2 ``var`` and ``nu`` degrees of freedom."""
    return -0.5 * (nu + 1.0) * np.log1p(resid ** 2 / (nu * var)) - 0.5 * np.log(var)


def grid_response(atlas: Atlas, a_p_deg: float, n_omega: int = 161, n_alpha: int = 31) -> GridResponse:
    """The atlas on the posterior grid for one amplitude, as cubic-spline interpolators along f_p.

    The atlas surface is evaluated once on (atlas f_p nodes) x (posterior grid); a probe then interpolates along
    f_p alone (a not-a-knot cubic spline, the same kind the atlas uses along f_p), which is exact at the nodes
    and costs a few microseconds per probe instead of an N-D interpolation of the whole grid. Built once per
    atlas, amplitude and grid (kept on the atlas).
    Returns a function ``f_hz -> (mean, spread, p_unstable)``, each (n_omega, n_alpha).
    """
    key = ("grid_response", float(a_p_deg), int(n_omega), int(n_alpha))
    return atlas.cached(key, lambda: _grid_response(atlas, float(a_p_deg), int(n_omega), int(n_alpha)))


def _grid_response(atlas: Atlas, a_p_deg: float, n_omega: int, n_alpha: int) -> GridResponse:
    from scipy.interpolate import CubicSpline

    w, a = posterior_grid(atlas, n_omega, n_alpha)
    ff, ww, aa = np.meshgrid(atlas.f_hz, w, a, indexing="ij")
    mean, spread, pu = atlas.predict(ff, a_p_deg, ww, aa)
    interps = [CubicSpline(atlas.f_hz, arr, axis=0) for arr in (mean, spread, pu)]
    lo, hi = float(atlas.f_hz[0]), float(atlas.f_hz[-1])

    def at(f_hz: float):
        f = min(max(float(f_hz), lo), hi)
        m, s, p = (it(f) for it in interps)
        return m, np.maximum(s, 0.0), np.clip(p, 0.0, 1.0)

    return at


def probe_log_likelihood(mu: np.ndarray, s: np.ndarray, p: np.ndarray, omega_b_deg_s: float, stderr_deg_s: float,
                         unstable: bool, sigma_model: float = SIGMA_MODEL) -> np.ndarray:
    """One probe's log-likelihood (module docstring) given the atlas's mean ``mu``, spread ``s`` (deg/s) and
    instability probability ``p`` at each grid object: ``log p`` for an unstable probe, ``log(1 - p)`` plus the
    Student-t term for a stable one, with p clipped to [P_MIN, 1 - P_MIN]."""
    p = np.clip(p, P_MIN, 1.0 - P_MIN)
    if unstable:
        return np.log(p)
    var = s ** 2 + stderr_deg_s ** 2 + sigma_model ** 2
    return np.log1p(-p) + log_student(omega_b_deg_s - mu, var)


def log_likelihood(atlas: Atlas, table: ProbeTable, n_omega: int = 161, n_alpha: int = 31,
                   sigma_model: float = SIGMA_MODEL) -> np.ndarray:
    """Sum of the probes' log-likelihoods on the posterior grid (shape (n_omega, n_alpha))."""
    total = np.zeros((n_omega, n_alpha))
    for k in range(len(table)):
        mu, s, p = grid_response(atlas, float(table.a_p_deg[k]), n_omega, n_alpha)(table.f_p_hz[k])
        total += probe_log_likelihood(mu, s, p, table.omega_b_deg_s[k], table.stderr_deg_s[k],
                                      bool(table.unstable[k]), sigma_model)
    return total


def posterior(atlas: Atlas, table: ProbeTable, sigma_model: float = SIGMA_MODEL, n_omega: int = 161,
              n_alpha: int = 31) -> Posterior:
    """The grid posterior over (omega_n, alpha) given the probes (a flat prior when there are none)."""
    w, a = posterior_grid(atlas, n_omega, n_alpha)
    logp = log_likelihood(atlas, table, n_omega, n_alpha, sigma_model)
    logp -= logp.max()
    prob = np.exp(logp)
    return Posterior(omega_n=w, alpha=a, prob=prob / prob.sum())


def identify_atlas(table: ProbeTable, physics: str = "tilelink", model: str = "pointmass", atlas: Atlas | None = None,
                   sigma_model: float = SIGMA_MODEL) -> Estimate:
    """Estimate omega_n and alpha as posterior means, with posterior std and credible intervals."""
    atlas = atlas if atlas is not None else load_atlas(physics, model)
    n_un = int(table.unstable.sum())
    try:
        for amp in table.amplitudes():
            atlas.amp_index(amp)
    except ValueError as exc:
        return Estimate(ok=False, method="atlas", reason=str(exc), n_probes=len(table), n_unstable=n_un)
    if len(table) == 0:
        return Estimate(ok=False, method="atlas", reason="no probes", n_probes=0)
    post = posterior(atlas, table, sigma_model)
    wm, ws, w68, w95 = post.omega_stats()
    am, asd, _, _ = post.alpha_stats()
    return Estimate(ok=True, method="atlas", omega_n=wm, omega_n_stderr=ws, omega_n_ci68=w68, omega_n_ci95=w95,
                    alpha=am, alpha_stderr=asd, n_probes=len(table), n_unstable=n_un, posterior=post)
