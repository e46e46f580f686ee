"""From a yaw trace to omega_B: whole-period averages and their standard error (pure functions)."""

from __future__ import annotations

import math

import numpy as np

#: Number of batch-means blocks used for the standard error (fewer when there are fewer periods).
N_BLOCKS = 10


def period_yaws(t: np.ndarray, yaw: np.ndarray, t0: float, period: float, n_periods: int) -> np.ndarray:
    """Yaw (rad) linearly interpolated at the period boundaries ``t0 + j*period``, j = 0..n_periods."""
    times = t0 + period * np.arange(n_periods + 1)
    return np.interp(times, t, yaw)


def rate_from_boundaries(boundary_yaw: np.ndarray, period: float) -> tuple[float, float]:
    """Mean angular velocity (rad/s) over the whole periods and its standard error by batch means.

    The per-period rates of a walking disc are correlated over a few periods, so they are grouped into at most
    ``N_BLOCKS`` consecutive blocks and the standard error is that of the block means. Needs >= 2 periods.
    """
    n = len(boundary_yaw) - 1
    if n < 1:
        return 0.0, 0.0
    mean = float((boundary_yaw[-1] - boundary_yaw[0]) / (n * period))
    if n < 2:
        return mean, abs(mean)
    n_blocks = min(N_BLOCKS, n)
    edges = np.linspace(0, n, n_blocks + 1).round().astype(int)
    block_rates = (boundary_yaw[edges[1:]] - boundary_yaw[edges[:-1]]) / ((edges[1:] - edges[:-1]) * period)
    stderr = float(np.std(block_rates, ddof=1) / math.sqrt(n_blocks))
    return mean, stderr


def measure_omega_b(t: np.ndarray, yaw: np.ndarray, t0: float, period: float, n_periods: int,
                    t_valid_end: float | None = None) -> tuple[float, float, int]:
    """omega_B (rad/s), its standard error (rad/s) and the number of whole periods used.

    Uses the periods of ``[t0, t0 + n_periods*period]`` that end before ``t_valid_end`` (the failure time of
    an unstable probe); returns zeros when no whole period is available.
    """
    if t_valid_end is not None:
        n_periods = min(n_periods, int(math.floor((t_valid_end - t0) / period + 1e-9)))
    if n_periods < 1:
        return 0.0, 0.0, 0
    yb = period_yaws(t, yaw, t0, period, n_periods)
    mean, se = rate_from_boundaries(yb, period)
    return mean, se, n_periods
