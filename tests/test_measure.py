"""omega_B and its standard error from a yaw trace (plate_env.measure), pinned on walks whose answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.physics.measure import N_BLOCKS, measure_omega_b, period_yaws, rate_from_boundaries


def _trace(yaw_at, t_end: float, fs: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, t_end + 0.5 / fs, 1.0 / fs)
    return t, yaw_at(t)


def test_rate_and_error_by_hand_on_four_periods():
    # per-period rates 2, 4, 2, 8 rad/s (period 0.5 s): mean 4, sample std sqrt(8), 4 blocks -> se sqrt(8)/2
    assert rate_from_boundaries(np.array([0.0, 1.0, 3.0, 4.0, 8.0]), 0.5) == pytest.approx((4.0, math.sqrt(2.0)),
                                                                                      rel=1e-14)


def test_linear_yaw_gives_its_rate_and_no_error_for_any_block_split():
    rate, period = -3.7, 1.0 / 23.0
    t, yaw = _trace(lambda t: 0.4 + rate * t, 2.0)
    for n_periods in (2, 7, 10, 23, 25):  # 25 periods: blocks of 2 and 3 periods (unequal lengths)
        omega, se, used = measure_omega_b(t, yaw, 0.3, period, n_periods)
        assert used == n_periods
        assert omega == pytest.approx(rate, rel=1e-12)
        assert abs(se) < 1e-9 * abs(rate)


def test_rate_uses_the_window_only():
    # the yaw turns at 5 rad/s before t0 and at 2 rad/s from t0 on: only the window's periods count
    t, yaw = _trace(lambda t: np.where(t < 0.5, 5.0 * t, 2.5 + 2.0 * (t - 0.5)), 2.0)
    omega, _, used = measure_omega_b(t, yaw, 0.5, 0.05, 20)
    assert used == 20 and omega == pytest.approx(2.0, rel=1e-12)


def test_period_boundaries_interpolate_the_samples():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    yaw = np.array([0.0, 1.0, 4.0, 9.0])
    np.testing.assert_allclose(period_yaws(t, yaw, 0.05, 0.1, 2), [0.5, 2.5, 6.5], rtol=1e-14)


def test_standard_error_on_random_walks_with_known_variance():
    """Per-period yaw steps i.i.d. N(rate T, s^2): the rate's true standard error over n periods is
    s / (T sqrt(n)). Batch means over 10 blocks must estimate it without bias (mean of se^2) and give the
    1-sigma coverage of a Student t with 9 degrees of freedom, P(|t_9| < 1) = 0.657."""
    rng = np.random.default_rng(42)
    period, rate, step_sd, n = 0.04, 7.5, 0.03, 40
    true_se = step_sd / (period * math.sqrt(n))
    se2, hits = [], []
    for _ in range(3000):
        yb = 0.2 + np.concatenate([[0.0], np.cumsum(rate * period + step_sd * rng.standard_normal(n))])
        mean, se = rate_from_boundaries(yb, period)
        se2.append(se ** 2)
        hits.append(abs(mean - rate) <= se)
    assert np.mean(se2) / true_se ** 2 == pytest.approx(1.0, abs=0.05)
    assert 0.62 <= np.mean(hits) <= 0.70


def test_at_most_n_blocks_and_one_period_is_its_own_error():
    rng = np.random.default_rng(1)
    yb = np.cumsum(rng.normal(1.0, 0.1, 201))
    period = 0.01
    mean, se = rate_from_boundaries(yb, period)
    block_rates = np.diff(yb[::20]) / (20 * period)  # 200 periods in exactly N_BLOCKS = 10 blocks of 20
    assert N_BLOCKS == 10
    assert mean == pytest.approx((yb[-1] - yb[0]) / (200 * period), rel=1e-14)
    assert se == pytest.approx(np.std(block_rates, ddof=1) / math.sqrt(10), rel=1e-12)
    # a single period has no spread to measure: its error is the whole rate
    assert rate_from_boundaries(np.array([1.0, 0.7]), 0.1) == pytest.approx((-3.0, 3.0), rel=1e-14)
    assert rate_from_boundaries(np.array([1.0]), 0.1) == (0.0, 0.0)


def test_unstable_probe_keeps_only_periods_finished_before_the_failure():
    rate, period, t0 = 1.5, 0.1, 0.2
    t, yaw = _trace(lambda t: rate * t, 3.0)
    assert measure_omega_b(t, yaw, t0, period, 20, t_valid_end=t0 + 3.5 * period)[2] == 3
    assert measure_omega_b(t, yaw, t0, period, 20, t_valid_end=t0 + 3 * period)[2] == 3  # boundary counts
    assert measure_omega_b(t, yaw, t0, period, 2, t_valid_end=t0 + 9 * period)[2] == 2  # never more than asked
    omega, se, used = measure_omega_b(t, yaw, t0, period, 20, t_valid_end=t0 + 0.9 * period)
    assert (omega, se, used) == (0.0, 0.0, 0)
    omega, se, used = measure_omega_b(t, yaw, t0, period, 20, t_valid_end=t0 + 1.5 * period)
    assert used == 1 and omega == pytest.approx(rate, rel=1e-12) and se == pytest.approx(rate, rel=1e-12)
