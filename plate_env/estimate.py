"""What an identification returns: an :class:`Estimate` of omega_n (and alpha) and, for the atlas method, the grid
:class:`Posterior` it came from. Plain frozen values; both identification methods (:mod:`plate_env.identify`,
:mod:`plate_env.inference`) build them, so they live below both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from plate_env.fitting import LorentzFit

#: (mean, standard deviation, 68 % interval, 95 % interval) of one posterior marginal.
MarginalStats = tuple[float, float, tuple[float, float], tuple[float, float]]


@dataclass(frozen=True)
class Posterior:
    """A normalised posterior on a grid: ``prob[i, j]`` for ``omega_n[i]`` (rad/s) and ``alpha[j]`` (rad)."""

    omega_n: np.ndarray
    alpha: np.ndarray
    prob: np.ndarray

    def marginal_omega(self) -> np.ndarray:
        return self.prob.sum(1)

    def marginal_alpha(self) -> np.ndarray:
        return self.prob.sum(0)

    @staticmethod
    def _stats(x: np.ndarray, p: np.ndarray) -> MarginalStats:
        mean = float(np.sum(p * x))
        std = float(math.sqrt(max(np.sum(p * (x - mean) ** 2), 0.0)))
        cdf = np.cumsum(p)
        cdf = cdf / cdf[-1]

        def q(level: float) -> float:
            return float(np.interp(level, cdf, x))

        return mean, std, (q(0.16), q(0.84)), (q(0.025), q(0.975))

    def omega_stats(self) -> MarginalStats:
        """(mean, std, 68 % interval, 95 % interval) of omega_n, rad/s."""
        return self._stats(self.omega_n, self.marginal_omega())

    def alpha_stats(self) -> MarginalStats:
        """(mean, std, 68 % interval, 95 % interval) of alpha, rad."""
        return self._stats(self.alpha, self.marginal_alpha())


@dataclass(frozen=True)
class Estimate:
    """An identification. ``ok`` False means no estimate could be made (``reason`` says why).

    Attributes:
        omega_n: omega_n_hat, rad/s; omega_n_stderr: rad/s; omega_n_ci68 / omega_n_ci95: credible or confidence
            intervals, rad/s.
        alpha: alpha_hat, rad (None when the method gives none); alpha_stderr: rad.
        fits: the per-amplitude Lorentzian fits (lorentz method), keyed by A_p in degrees.
        posterior: the atlas posterior (atlas method), else None.
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
    fits: dict[float, LorentzFit] = field(default_factory=dict, compare=False, repr=False)
    posterior: Posterior | None = field(default=None, compare=False, repr=False)

    def relative_error(self, omega_n_true: float) -> float:
        """|omega_n_hat - omega_n_true| / omega_n_true; inf when there is no estimate."""
        return abs(self.omega_n - omega_n_true) / omega_n_true if self.ok else math.inf

    def to_dict(self) -> dict:
        """JSON-ready summary in edge units (the posterior grid is left out)."""
        d = {"ok": self.ok, "method": self.method, "reason": self.reason, "omega_n_rad_s": self.omega_n,
             "omega_n_stderr_rad_s": self.omega_n_stderr, "omega_n_pi": self.omega_n / math.pi,
             "omega_n_ci68_rad_s": list(self.omega_n_ci68), "omega_n_ci95_rad_s": list(self.omega_n_ci95),
             "alpha_deg": math.degrees(self.alpha) if self.alpha is not None else None,
             "alpha_stderr_deg": math.degrees(self.alpha_stderr), "n_probes": self.n_probes,
             "n_unstable": self.n_unstable}
        d["fits"] = {f"{a:g}": fit.to_dict() for a, fit in self.fits.items()}
        return d
