"""Summaries the experiment scripts report, computed one way (pure numpy)."""

from __future__ import annotations

import numpy as np


def median_p90(values) -> tuple[float, float]:
    """Median and 90th percentile (numpy's linear interpolation between order statistics) of ``values``.

    Used for every "median / 90th pct" column in ``experiments/results/``; raises ValueError on no values
    rather than returning NaN into a table."""
    x = np.asarray(values, dtype=float).ravel()
    if x.size == 0:
        raise ValueError("median_p90 of no values")
    return float(np.median(x)), float(np.percentile(x, 90.0))
