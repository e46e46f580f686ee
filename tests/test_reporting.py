"""The shared report helpers: median / 90th percentile, and figures made and saved without pyplot."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from plate_env.bench.reporting import median_p90


def test_median_p90_matches_numpy_and_refuses_no_values():
    x = [5.0, 1.0, 4.0, 2.0, 3.0, 10.0]
    assert median_p90(x) == (3.5, 7.5)  # 90th pct at rank 0.9 * 5 = 4.5: halfway from 5 to 10
    rng = np.random.default_rng(0)
    y = rng.lognormal(size=101)
    assert median_p90(y) == (float(np.median(y)), float(np.percentile(y, 90)))
    with pytest.raises(ValueError, match="no values"):
        median_p90([])


def test_figures_are_saved_without_a_backend_choice_or_an_open_pyplot_figure(tmp_path):
    code = f"""
import sys, matplotlib
backend = matplotlib.get_backend()
from plate_env.plotting import new_figure, save_figure
fig, axes = new_figure(1, 2, figsize=(4, 2), sharey=True)
axes[0].plot([0, 1], [1, 2])
path = save_figure(fig, {str(tmp_path / 'f.png')!r}, dpi=50)
open_figures = sys.modules["matplotlib.pyplot"].get_fignums() if "matplotlib.pyplot" in sys.modules else []
print(path.stat().st_size > 500, open_figures == [], matplotlib.get_backend() == backend)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "True", "True"]


def test_a_bound_counts_for_95_percent_coverage_only_when_it_holds():
    """A bound (an answer at the edge of the identifiable range) is a 95 % statement: it covers the truth when
    the truth lies on its side; it never counts as an estimate (error inf, no 68 % interval)."""
    from plate_env.bench.scoring import per_object
    from plate_env.identify.estimate import Estimate

    above = Estimate(ok=False, method="atlas", reason="edge", bound=("above", 100.0))
    below = Estimate(ok=False, method="atlas", reason="edge", bound=("below", 10.0))
    none = Estimate(ok=False, method="atlas", reason="no probes")
    d = per_object([150.0, 50.0, 5.0, 50.0, 5.0], [above, above, below, below, none])
    assert d["in95"].tolist() == [1.0, 0.0, 1.0, 0.0, 0.0]
    assert d["in68"].tolist() == [0.0] * 5 and np.isinf(d["error"]).all() and d["ok"].tolist() == [0.0] * 5
