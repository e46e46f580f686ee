"""Bootstrap intervals over objects (plate_env.scoring) on cases with a known answer: their coverage is measured,
not assumed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.bench.scoring import bootstrap, paired_difference, score

REPS = 300
#: 95 % intervals over REPS independent samples: the binomial 99.9 % band of the coverage around 0.95 is about
#: 0.91-0.98; percentile intervals of a median of 100 run slightly under nominal, hence the lower edge.
COVER = (0.88, 0.99)


def _coverage(draw, truth: float, fn, n_boot: int = 400) -> float:
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(REPS):
        s = bootstrap(draw(rng), fn, rng, n_boot)
        hits += s.lo <= truth <= s.hi
    return hits / REPS


def test_bootstrap_interval_of_a_median_covers_the_true_median():
    cov = _coverage(lambda rng: rng.exponential(1.0, 100), math.log(2), lambda x: np.median(x, axis=-1))
    assert COVER[0] <= cov <= COVER[1]


def test_bootstrap_interval_of_a_rate_covers_the_true_rate():
    cov = _coverage(lambda rng: (rng.random(100) < 0.2).astype(float), 0.2, lambda x: x.mean(-1))
    assert COVER[0] <= cov <= COVER[1]


def test_bootstrap_over_a_whole_curve_resamples_objects_not_points():
    """A per-object curve (objects x budgets) reduced to one number per resample: the interval of its mean must
    cover the truth as a per-object mean does (resampling the budget axis instead would not vary it at all)."""
    grid = np.linspace(0.0, 1.0, 21)

    def draw(rng):
        level = rng.normal(0.5, 0.2, 100)  # each object one level, the same at every budget
        return level[:, None] * np.ones_like(grid)

    cov = _coverage(draw, 0.5, lambda x: x.mean(axis=-2).mean(axis=-1))
    assert COVER[0] <= cov <= COVER[1]


def test_paired_difference_interval_covers_a_known_shift():
    rng = np.random.default_rng(2)
    hits = 0
    for _ in range(REPS):
        b = rng.exponential(0.1, 80)
        a = b + 0.05 + rng.laplace(0.0, 0.01, 80)  # symmetric noise: the median difference is 0.05
        s = paired_difference(a, b, rng, 400)
        hits += s.lo <= 0.05 <= s.hi
    assert COVER[0] <= hits / REPS <= COVER[1]


def test_identical_values_give_a_point_interval_and_no_estimate_counts_as_infinite():
    s = bootstrap(np.full(30, 0.07), lambda x: np.median(x, axis=-1), np.random.default_rng(0))
    assert (s.value, s.lo, s.hi) == (0.07, 0.07, 0.07)

    class E:
        def __init__(self, ok, w):
            self.ok, self.omega_n, self.omega_n_ci68, self.omega_n_ci95 = ok, w, (w - 1, w + 1), (w - 2, w + 2)

    sc = score([10.0] * 4, [E(True, 10.5), E(True, 9.0), E(False, 0.0), E(False, 0.0)], np.random.default_rng(0), 200)
    assert sc.no_estimate.value == 0.5 and sc.median_error.value == math.inf
    assert sc.coverage95.value == pytest.approx(0.5)  # 10 is inside both estimates' 95 % intervals, none of the others


def test_bootstrap_refuses_no_objects():
    with pytest.raises(ValueError, match="no objects"):
        bootstrap([], np.mean, np.random.default_rng(0))


def test_quantiles_with_no_estimates_are_inf_or_an_estimate_never_nan():
    from plate_env.bench.scoring import _percentile

    x = np.array([0.01, 0.02, math.inf, math.inf])
    assert _percentile(x, 100 / 3) == 0.02  # exactly on an order statistic (numpy: 0 * inf = NaN)
    assert _percentile(x, 90) == math.inf  # between two no-estimates (numpy: inf - inf = NaN)
    assert _percentile(x, 50) == math.inf and _percentile(x, 20) == pytest.approx(0.016)
    s = bootstrap(np.r_[np.full(90, 0.05), np.full(10, math.inf)], lambda v: _percentile(v, 90),
                  np.random.default_rng(0))
    assert not any(math.isnan(v) for v in (s.value, s.lo, s.hi))
