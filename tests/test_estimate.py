"""What identification returns (plate_env.estimate): the posterior's summaries, the edge rule and the estimate's
contracts and report, pinned on grids whose answers are worked by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.identify.estimate import Estimate, Posterior, marginal


def test_marginal_quantiles_by_hand():
    """Cells at x = 0, 1, 2, 3 with masses .1, .2, .3, .4: cell edges (0, .5, 1.5, 2.5, 3) and cdf at the edges
    (0, .1, .3, .6, 1). The median interpolates between edges 1.5 (cdf 0.3) and 2.5 (cdf 0.6)."""
    x = np.array([0.0, 1.0, 2.0, 3.0])
    p = np.array([0.1, 0.2, 0.3, 0.4])
    m = marginal(x, p)
    assert m.value == pytest.approx(1.5 + (0.5 - 0.3) / 0.3)
    assert m.ci68 == pytest.approx((0.5 + (0.16 - 0.1) / 0.2, 2.5 + (0.84 - 0.6) / 0.4 * 0.5))
    assert m.ci95 == pytest.approx((0.025 / 0.1 * 0.5, 2.5 + (0.975 - 0.6) / 0.4 * 0.5))
    assert m.stderr == pytest.approx((m.ci68[1] - m.ci68[0]) / 2)
    logm = marginal(np.log([1.0, 2.0, 4.0, 8.0]), p, np.exp)
    # the same masses on a log2 grid: quantiles interpolate in log, then map back
    assert logm.value == pytest.approx(2.0 ** (1.5 + (0.5 - 0.3) / 0.3), rel=1e-12)
    assert logm.ci68[0] == pytest.approx(2.0 ** (0.5 + (0.16 - 0.1) / 0.2), rel=1e-12)
    assert logm.stderr == pytest.approx((logm.ci68[1] - logm.ci68[0]) / 2)


def test_a_one_cell_posterior_keeps_a_grid_step_wide_interval():
    x = np.linspace(0.0, 1.0, 11)
    p = np.zeros(11)
    p[5] = 1.0
    m = marginal(x, p, floor=0.1)
    assert m.value == pytest.approx(0.5) and m.ci68[1] - m.ci68[0] == pytest.approx(0.1)
    assert m.ci95[0] <= m.ci68[0] and m.ci95[1] >= m.ci68[1] and m.stderr == pytest.approx(0.05)


def _posterior(pw, lo_hi=(2.0, 8.0)) -> Posterior:
    w = np.geomspace(1.0, 16.0, len(pw))
    return Posterior(omega_n=w, alpha=np.array([0.2, 0.4]), prob=np.outer(pw, [0.5, 0.5]), sigma_conv=0.1,
                     identifiable_range=lo_hi)


def test_posterior_marginals_and_the_edge_rule():
    pw = np.zeros(41)
    pw[20] = 1.0  # omega 4: inside (2, 8)
    post = _posterior(pw)
    np.testing.assert_allclose(post.marginal_omega(), pw)
    np.testing.assert_allclose(post.marginal_alpha(), [0.5, 0.5])
    assert post.edge() is None and post.omega().value == pytest.approx(4.0, rel=0.05)
    high = np.zeros(41)
    high[38:] = 1.0  # omega 13-16: above 8 * exp(-0.2)
    assert _posterior(high / high.sum()).edge() == "above"
    low = np.zeros(41)
    low[:3] = 1.0
    assert _posterior(low / low.sum()).edge() == "below"
    tiny = pw * 0.97
    tiny[40] = 0.03  # 3 % beyond the range: still an estimate
    assert _posterior(tiny).edge() is None


def test_estimates_never_contradict_their_intervals():
    with pytest.raises(ValueError, match="inconsistent estimate"):
        Estimate(ok=True, method="atlas", omega_n=13.0, omega_n_ci68=(10.5, 11.5), omega_n_ci95=(10.0, 12.0))
    with pytest.raises(ValueError, match="inconsistent estimate"):
        Estimate(ok=True, method="atlas", omega_n=11.0, omega_n_ci68=(9.5, 11.5), omega_n_ci95=(10.0, 12.0))
    Estimate(ok=False, method="atlas", omega_n=13.0, omega_n_ci68=(10.5, 11.5))  # no estimate: nothing promised


def test_relative_error_and_report():
    est = Estimate(ok=True, method="atlas", omega_n=11.0, omega_n_stderr=0.5, omega_n_ci68=(10.5, 11.5),
                   omega_n_ci95=(10.0, 12.0), alpha=math.radians(40.0), alpha_stderr=math.radians(2.0), n_probes=7,
                   n_unstable=2, forward="lab")
    assert est.relative_error(10.0) == pytest.approx(0.1, rel=1e-12)
    assert est.relative_error(12.5) == pytest.approx(0.12, rel=1e-12)
    assert Estimate(ok=False, method="atlas", omega_n=10.0).relative_error(10.0) == math.inf
    assert est.to_dict() == {"ok": True, "method": "atlas", "reason": None, "forward": "lab", "omega_n_rad_s": 11.0,
                             "omega_n_stderr_rad_s": 0.5, "omega_n_pi": 11.0 / math.pi,
                             "omega_n_ci68_rad_s": [10.5, 11.5], "omega_n_ci95_rad_s": [10.0, 12.0],
                             "alpha_deg": pytest.approx(40.0), "alpha_stderr_deg": pytest.approx(2.0),
                             "n_probes": 7, "n_unstable": 2, "bound": None, "beyond": None, "fits": {}, "check": None,
                             "note": None}
    none = Estimate(ok=False, method="lorentz", reason="no probes").to_dict()
    assert none["alpha_deg"] is None and none["reason"] == "no probes" and none["ok"] is False
    bound = Estimate(ok=False, method="atlas", reason="above", bound=("above", 130.0)).to_dict()
    assert bound["bound"] == {"side": "above", "omega_n_rad_s": 130.0}


def test_an_estimate_comes_back_from_its_dict():
    est = Estimate(ok=False, method="atlas", reason="edge", omega_n=40.0, omega_n_stderr=2.0,
                   omega_n_ci68=(38.0, 42.0), omega_n_ci95=(36.0, 45.0), alpha=0.7, alpha_stderr=0.01,
                   bound=("above", 36.0), beyond="above", forward="lab", n_probes=12, n_unstable=3)
    back = Estimate.from_dict(est.to_dict())
    assert back.to_dict() == est.to_dict()
    assert back.bound == ("above", 36.0) and back.beyond == "above" and back.alpha == pytest.approx(0.7)
