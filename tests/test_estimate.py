"""What identification returns (plate_env.estimate): the posterior's summaries and the estimate's report, pinned
on a grid whose answers are worked by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.estimate import Estimate, Posterior


def _posterior() -> Posterior:
    """omega_n on (0.5, 1.0, 1.5, 2.0) with p (0.1, 0.2, 0.3, 0.4): mean 1.5, variance 0.25, cdf (.1, .3, .6, 1);
    alpha on (0.2, 0.4) with p (0.75, 0.25): mean 0.25, variance 0.0075."""
    pw = np.array([0.1, 0.2, 0.3, 0.4])
    pa = np.array([0.75, 0.25])
    return Posterior(omega_n=np.array([0.5, 1.0, 1.5, 2.0]), alpha=np.array([0.2, 0.4]), prob=np.outer(pw, pa))


def test_marginal_mean_std_and_interval_ends_by_hand():
    post = _posterior()
    np.testing.assert_allclose(post.marginal_omega(), [0.1, 0.2, 0.3, 0.4], rtol=1e-12)
    np.testing.assert_allclose(post.marginal_alpha(), [0.75, 0.25], rtol=1e-12)
    mean, std, (lo68, hi68), (lo95, hi95) = post.omega_stats()
    assert (mean, std) == pytest.approx((1.5, 0.5), rel=1e-12)
    # quantiles interpolate the cdf at the grid points: 0.16 -> 0.5 + 0.5 * 0.06 / 0.2, 0.84 -> 1.5 + 0.5 * 0.24 / 0.4
    assert (lo68, hi68) == pytest.approx((0.65, 1.8), rel=1e-12)
    assert (lo95, hi95) == pytest.approx((0.5, 1.96875), rel=1e-12)  # below the first cdf value: the grid's start
    a_mean, a_std, (a_lo, a_hi), _ = post.alpha_stats()
    assert (a_mean, a_std) == pytest.approx((0.25, math.sqrt(0.0075)), rel=1e-12)
    assert (a_lo, a_hi) == pytest.approx((0.2, 0.2 + 0.2 * 0.09 / 0.25), rel=1e-12)


def test_relative_error_and_report():
    est = Estimate(ok=True, method="atlas", omega_n=11.0, omega_n_stderr=0.5, omega_n_ci68=(10.5, 11.5),
                   omega_n_ci95=(10.0, 12.0), alpha=math.radians(40.0), alpha_stderr=math.radians(2.0), n_probes=7,
                   n_unstable=2)
    assert est.relative_error(10.0) == pytest.approx(0.1, rel=1e-12)
    assert est.relative_error(12.5) == pytest.approx(0.12, rel=1e-12)
    assert Estimate(ok=False, method="atlas", omega_n=10.0).relative_error(10.0) == math.inf
    assert est.to_dict() == {"ok": True, "method": "atlas", "reason": None, "omega_n_rad_s": 11.0,
                             "omega_n_stderr_rad_s": 0.5, "omega_n_pi": 11.0 / math.pi,
                             "omega_n_ci68_rad_s": [10.5, 11.5], "omega_n_ci95_rad_s": [10.0, 12.0],
                             "alpha_deg": pytest.approx(40.0), "alpha_stderr_deg": pytest.approx(2.0),
                             "n_probes": 7, "n_unstable": 2, "fits": {}}
    none = Estimate(ok=False, method="lorentz", reason="no probes").to_dict()
    assert none["alpha_deg"] is None and none["reason"] == "no probes" and none["ok"] is False
