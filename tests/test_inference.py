"""Model-based identification (plate_env.inference): the likelihood term by term, the forward model's pooling,
discrepancy and blur, the estimate's contracts (a point inside its intervals, no collapse below the grid, bounds at
the edge of the identifiable range), and the maximum-likelihood error estimates."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.forward import ForwardModel, Member
from plate_env.identify.inference import (
    NU,
    blurred,
    fit_sigma_eps,
    fit_sigma_model,
    identify_atlas,
    log_student,
    member_log_likelihood,
    member_response,
    posterior,
    smoothed_p,
)

N_OMEGA, N_ALPHA = 41, 7
SIGMA = 5.0


def _fm(atlas, sigma_model=SIGMA, blur=0.0, sigma_eps=0.0, **kw) -> ForwardModel:
    return ForwardModel("toy", (Member(atlas, sigma_model, blur=blur),), sigma_eps=sigma_eps, **kw)


def _one(atlas, f, y, se, unstable, sigma_model=SIGMA, blur=0.0):
    fm = _fm(atlas, sigma_model, blur)
    w, a = fm.grid(N_OMEGA, N_ALPHA)
    return member_log_likelihood(fm.members[0], ProbeTable.from_arrays([f], 3.0, [y], [se], [unstable]), w, a)[0], w, a


def test_log_student_is_the_student_t_density_up_to_a_constant():
    rng = np.random.default_rng(0)
    resid = rng.normal(0, 40, 200)
    var = rng.uniform(10, 2000, 200)
    ref = stats.t.logpdf(resid, df=NU, scale=np.sqrt(var))
    assert NU == 4.0
    assert np.ptp(log_student(resid, var) - ref) < 1e-9  # the same function of (resid, var), shifted by a constant


def test_instability_shares_are_shrunk_by_jeffreys_rule():
    np.testing.assert_allclose(smoothed_p(np.array([0.0, 0.25, 1.0]), 4), [0.1, 0.3, 0.9])
    assert smoothed_p(np.array([0.0]), 1)[0] == pytest.approx(0.25)


def test_an_unstable_probe_contributes_the_smoothed_instability_probability(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    ll, w, a = _one(atlas, 30.0, 0.0, 0.0, True)
    _, _, p = member_response(Member(atlas, SIGMA), 3.0, w, a)[0](30.0)
    np.testing.assert_allclose(ll, np.log(smoothed_p(p, 3)), rtol=0, atol=1e-12)
    assert ll.min() == pytest.approx(math.log(0.125)) and ll.max() == pytest.approx(math.log(0.875))


def test_a_stable_probe_contributes_stability_times_student_t(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    y, e = 310.0, 6.0
    ll, w, a = _one(atlas, 30.0, y, e, False)
    mu, s, p = member_response(Member(atlas, SIGMA), 3.0, w, a)[0](30.0)
    expected = np.log1p(-smoothed_p(p, 3)) + log_student(y - mu, s ** 2 + e ** 2 + SIGMA ** 2)
    np.testing.assert_allclose(ll, expected, rtol=0, atol=1e-12)


def test_probes_add_their_log_likelihoods(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    rows = [(18.0, 150.0, 3.0, False), (30.0, 0.0, 0.0, True), (24.0, 400.0, 5.0, False)]
    fm = _fm(atlas, blur=0.05)
    w, a = fm.grid(N_OMEGA, N_ALPHA)
    f, y, se, un = (list(c) for c in zip(*rows, strict=True))
    total, skipped = member_log_likelihood(fm.members[0], ProbeTable.from_arrays(f, 3.0, y, se, un), w, a)
    parts = sum(_one(atlas, *row, blur=0.05)[0] for row in rows)
    np.testing.assert_allclose(total, parts, rtol=0, atol=1e-9)
    assert skipped == 0


def test_blur_averages_the_likelihood_along_log_omega():
    ll = np.full((41, 3), -50.0)
    ll[20] = 0.0
    out = blurred(ll, 2.0)
    assert out[20, 0] < 0.0 and out[18, 0] > -50.0  # the spike is spread over neighbours
    np.testing.assert_allclose(np.exp(out).sum(0), np.exp(ll).sum(0), rtol=1e-3)  # as a likelihood, mass kept
    np.testing.assert_array_equal(blurred(ll, 0.0), ll)


def test_unstable_probes_move_the_posterior_to_objects_that_go_unstable(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    fm = _fm(atlas)
    f = [28.0, 32.0, 36.0]
    unstable = posterior(fm, ProbeTable.from_arrays(f, 3.0, [0.0] * 3, [0.0] * 3, [True] * 3), N_OMEGA, N_ALPHA)
    stiff = unstable.omega_n > 12 * math.pi
    assert unstable.marginal_omega()[stiff].sum() > 0.8
    mu, _, _ = atlas.predict(np.array(f), 3.0, 4 * math.pi, 0.7)
    stable = posterior(fm, ProbeTable.from_arrays(f, 3.0, mu, [2.0] * 3, [False] * 3), N_OMEGA, N_ALPHA)
    assert stable.marginal_omega()[stiff].sum() < 0.1


def test_estimate_keeps_its_contracts_and_refuses_probes_no_member_describes(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    table = ProbeTable.from_arrays([20.0, 28.0, 32.0], 3.0, [300.0, 0.0, 0.0], [3.0, 0.0, 0.0], [False, True, True])
    est = identify_atlas(table, _fm(atlas))
    # one stable probe: alpha piles at the top of the toy's 30-60 deg, which the alpha edge rule flags (issue 28);
    # the numbers it carries keep the contracts all the same
    assert not est.ok and "alpha is above the friction angles 'toy' covers" in est.reason
    assert est.method == "atlas" and est.n_probes == 3 and est.n_unstable == 2 and est.forward == "toy"
    lo, hi = est.omega_n_ci95
    assert lo <= est.omega_n_ci68[0] <= est.omega_n <= est.omega_n_ci68[1] <= hi
    assert est.omega_n_stderr == pytest.approx((est.omega_n_ci68[1] - est.omega_n_ci68[0]) / 2)
    m = est.posterior.omega()
    assert (est.omega_n, est.omega_n_ci68, est.omega_n_ci95) == (m.value, m.ci68, m.ci95)
    assert est.posterior.prob.sum() == pytest.approx(1.0)
    bad = identify_atlas(ProbeTable.from_arrays([20.0, 21.0], 12.0, [1.0, 0.0], unstable=[False, True]), _fm(atlas))
    assert (bad.ok, bad.n_probes, bad.n_unstable) == (False, 2, 1) and "A_p = 12 deg is not in" in bad.reason
    empty = identify_atlas(ProbeTable.from_arrays([], [], []), _fm(atlas))
    assert (empty.ok, empty.reason) == (False, "no probes")


def _sweep_from_atlas(atlas, w_true, a_true, f, rng, sigma=SIGMA):
    mu, s, _ = atlas.predict(f, 3.0, w_true, a_true)
    return ProbeTable.from_arrays(f, 3.0, mu + rng.normal(0, 1, f.size) * np.sqrt(s ** 2 + sigma ** 2),
                                  np.zeros(f.size))


def test_intervals_cover_the_truth_at_their_rates_on_data_drawn_from_the_forward_model(toy_atlas):
    """Simulation-based calibration, fast version: objects from the prior, probes from the forward model itself."""
    atlas = toy_atlas()
    fm = _fm(atlas)
    rng = np.random.default_rng(5)
    in68 = in95 = 0
    n = 60
    for _ in range(n):
        w_true = math.exp(rng.uniform(math.log(3 * math.pi), math.log(30 * math.pi)))
        est = identify_atlas(_sweep_from_atlas(atlas, w_true, math.radians(rng.uniform(32, 58)),
                                               rng.uniform(14, 36, 8), rng), fm)
        in68 += est.omega_n_ci68[0] <= w_true <= est.omega_n_ci68[1]
        in95 += est.omega_n_ci95[0] <= w_true <= est.omega_n_ci95[1]
    assert 0.52 <= in68 / n <= 0.84 and in95 / n >= 0.88, (in68, in95)


def test_ten_thousand_probes_do_not_collapse_the_posterior_below_its_grid(toy_atlas):
    """A 10,000-row sweep (a Lorentzian no member exactly describes, 5 deg/s noise): the estimate lies inside its
    intervals, its stderr agrees with them and is at least half a grid step of log omega wide."""
    atlas = toy_atlas()
    f = np.linspace(10.0, 40.0, 10_000)
    rng = np.random.default_rng(1)
    y = 600.0 / (1 + ((f - 25.0) / 5.0) ** 2) + rng.normal(0, 5.0, f.size)
    fm = _fm(atlas)
    est = identify_atlas(ProbeTable.from_arrays(f, 3.0, y, np.full(f.size, 5.0)), fm)
    assert est.omega_n_ci95[0] <= est.omega_n_ci68[0] <= est.omega_n <= est.omega_n_ci68[1] <= est.omega_n_ci95[1]
    from plate_env.identify.inference import N_OMEGA as n_default

    w, _ = fm.grid(n_default, 31)
    step = math.log(w[1] / w[0])
    assert math.log(est.omega_n_ci68[1] / est.omega_n_ci68[0]) >= step * 0.99
    assert est.omega_n_stderr == pytest.approx((est.omega_n_ci68[1] - est.omega_n_ci68[0]) / 2)
    assert math.degrees(est.alpha_stderr) > 0.1


def test_a_truth_outside_the_identifiable_range_is_reported_as_a_bound(toy_atlas):
    atlas = toy_atlas()  # omega_n 2pi-40pi
    fm = _fm(atlas)
    f = np.arange(10.0, 40.1, 1.0)
    rng = np.random.default_rng(2)
    for w_out, side in ((60 * math.pi, "above"), (1.0 * math.pi, "below")):
        # an object beyond the range: its curve continues the atlas's trend (the toy law evaluated outside it)
        f0 = 22 + 6 * math.log(w_out / (2 * math.pi)) / math.log(20) - 4 * (0.7 - 0.7)
        y = (400 + 200 * math.log(w_out / math.pi) / 4) / (1 + ((f - f0) / 4.5) ** 2) + rng.normal(0, 2, f.size)
        est = identify_atlas(ProbeTable.from_arrays(f, 3.0, y, np.full(f.size, 2.0)), fm)
        assert not est.ok and est.bound is not None and est.bound[0] == side, (side, est.reason)
        assert side in est.reason and "at 95 %" in est.reason
    inside = identify_atlas(_sweep_from_atlas(atlas, 10 * math.pi, 0.7, f, rng), fm)
    assert inside.ok and inside.bound is None


def test_a_discrepancy_lets_the_posterior_reach_beyond_the_range_without_making_a_bound(toy_atlas):
    """With sigma_eps the truth may lie outside the models' range by the discrepancy: the grid reaches PAD_SIGMAS
    of it beyond each end (no mass lost at the edge), and an object well inside the range, near its top, stays an
    estimate: the edge rule reads the models' own posterior, not the one widened by the discrepancy."""
    from plate_env.identify.forward import PAD_SIGMAS

    atlas = toy_atlas()  # omega_n 2pi-40pi
    fm = _fm(atlas, sigma_eps=0.3)
    w, _ = fm.grid(N_OMEGA, N_ALPHA)
    assert w[0] <= 2 * math.pi * math.exp(-PAD_SIGMAS * 0.3) * 1.0001
    assert w[-1] >= 40 * math.pi * math.exp(PAD_SIGMAS * 0.3) * 0.9999
    steps = np.diff(np.log(w))
    assert np.ptp(steps) < 1e-9 and steps[0] == pytest.approx(math.log(20) / (N_OMEGA - 1))
    table = _sweep_from_atlas(atlas, 28 * math.pi, 0.7, np.arange(12.0, 40.0, 1.0), np.random.default_rng(5))
    est = identify_atlas(table, fm)
    assert est.ok and est.bound is None, est.reason
    assert est.omega_n_ci95[1] > 40 * math.pi  # the discrepancy reaches past the top node
    assert est.omega_n == pytest.approx(28 * math.pi, rel=0.15)
    # without the padding, mass beyond the range would be cut: the interval would end at the top node
    assert identify_atlas(table, _fm(atlas)).omega_n_ci95[1] <= 40 * math.pi * 1.0001


def test_a_coherent_discrepancy_widens_the_posterior(toy_atlas):
    atlas = toy_atlas()
    table = _sweep_from_atlas(atlas, 10 * math.pi, 0.7, np.arange(14.0, 36.0, 2.0), np.random.default_rng(3))
    narrow = identify_atlas(table, _fm(atlas, sigma_eps=0.0))
    wide = identify_atlas(table, _fm(atlas, sigma_eps=0.2))
    half = {k: math.log(e.omega_n_ci68[1] / e.omega_n_ci68[0]) / 2 for k, e in (("narrow", narrow), ("wide", wide))}
    # the discrepancy adds its variance to the posterior's own (a normal convolved along log omega)
    assert half["wide"] == pytest.approx(math.hypot(half["narrow"], 0.2), rel=0.1)
    assert half["wide"] > 2 * half["narrow"]


def test_evidence_pooling_picks_the_member_whose_curves_fit(toy_atlas):
    a, b = toy_atlas(1.0), toy_atlas(1.4)
    a, b = dataclasses.replace(a, model="a"), dataclasses.replace(b, model="b")
    fm = ForwardModel("two", (Member(a, SIGMA), Member(b, SIGMA)))
    table = _sweep_from_atlas(b, 12 * math.pi, 0.8, np.arange(14.0, 36.0, 1.0), np.random.default_rng(4))
    post = posterior(fm, table, N_OMEGA, N_ALPHA)
    assert post.members == ("toy/a", "toy/b") and post.member_weights[1] > 0.99
    fixed = posterior(dataclasses.replace(fm, pooling="fixed"), table, N_OMEGA, N_ALPHA)
    assert fixed.member_weights == pytest.approx((0.5, 0.5))


def test_fit_sigma_model_recovers_a_known_model_error():
    rng = np.random.default_rng(0)
    spread, stderr = rng.uniform(0.5, 3.0, 4000), rng.uniform(0.2, 1.0, 4000)
    resid = rng.normal(0, 1, 4000) * np.sqrt(spread ** 2 + stderr ** 2 + 4.0 ** 2)
    assert fit_sigma_model(resid, spread, stderr, nu=1e6) == pytest.approx(4.0, rel=0.05)
    with pytest.raises(ValueError, match="no held-out residuals"):
        fit_sigma_model(np.array([]), np.array([]), np.array([]))


def test_fit_sigma_eps_recovers_a_known_discrepancy_and_is_zero_without_one():
    rng = np.random.default_rng(1)
    sd = rng.uniform(0.02, 0.08, 3000)
    assert fit_sigma_eps(rng.normal(0, 1, 3000) * np.sqrt(sd ** 2 + 0.1 ** 2), sd) == pytest.approx(0.1, rel=0.06)
    assert fit_sigma_eps(rng.normal(0, 1, 3000) * sd * 0.9, sd) == 0.0




def test_intervals_keep_their_coverage_on_a_model_left_out_once_the_discrepancy_is_estimated(toy_atlas):
    """Simulation-based calibration across models, fast version: data from a second model whose curves sit at
    objects shifted by a random exp(eps) (sd 0.25) through a forward model of the first. Without a discrepancy term
    the 95 % intervals miss; with sigma_eps fitted (maximum likelihood) on a calibration set of other objects they
    hold at their rate on a test set."""
    atlas = toy_atlas()
    rng = np.random.default_rng(11)
    f = np.arange(12.0, 38.0, 2.0)

    def draw(n):
        out = []
        for _ in range(n):
            w = math.exp(rng.uniform(math.log(6 * math.pi), math.log(18 * math.pi)))  # shifted, still inside
            a = math.radians(rng.uniform(33, 57))
            out.append((w, _sweep_from_atlas(atlas, w * math.exp(rng.normal(0, 0.25)), a, f, rng)))
        return out

    fm0 = _fm(atlas)
    cal = draw(80)
    eps = np.array([math.log(w / identify_atlas(t, fm0).omega_n) for w, t in cal])
    sd = np.array([math.log(e.omega_n_ci68[1] / e.omega_n_ci68[0]) / 2 for e in (identify_atlas(t, fm0)
                                                                                for _, t in cal)])
    sigma = fit_sigma_eps(eps, sd)
    assert 0.17 < sigma < 0.33
    test = draw(80)
    naive = np.mean([identify_atlas(t, fm0).omega_n_ci95[0] <= w <= identify_atlas(t, fm0).omega_n_ci95[1]
                     for w, t in test])
    fm = _fm(atlas, sigma_eps=sigma)
    ests = [(w, identify_atlas(t, fm)) for w, t in test]
    c95 = np.mean([e.omega_n_ci95[0] <= w <= e.omega_n_ci95[1] for w, e in ests])
    c68 = np.mean([e.omega_n_ci68[0] <= w <= e.omega_n_ci68[1] for w, e in ests])
    assert naive < 0.8 and c95 >= 0.88 and 0.5 <= c68 <= 0.85, (naive, c68, c95)


def test_a_student_t_discrepancy_has_heavier_tails_and_is_fitted_as_such(toy_atlas):
    """Across models the errors are heavy-tailed: a forward model may carry a Student-t discrepancy. Its 95 %
    interval reaches further, relative to the 68 % one, than a normal one of the same scale, and fit_sigma_eps with
    ``nu`` recovers the scale of t-distributed errors (where the normal fit is inflated by the tail)."""
    atlas = toy_atlas()
    table = _sweep_from_atlas(atlas, 10 * math.pi, 0.7, np.arange(14.0, 36.0, 2.0), np.random.default_rng(3))
    normal = identify_atlas(table, _fm(atlas, sigma_eps=0.2))
    heavy = identify_atlas(table, _fm(atlas, sigma_eps=0.2, eps_nu=3.0))

    def ratio(e):
        return math.log(e.omega_n_ci95[1] / e.omega_n_ci95[0]) / math.log(e.omega_n_ci68[1] / e.omega_n_ci68[0])

    assert ratio(normal) == pytest.approx(1.96, rel=0.08)
    assert ratio(heavy) > 1.25 * ratio(normal)  # t3: 3.18 / 1.20 = 2.7 against 1.96
    rng = np.random.default_rng(7)
    sd = rng.uniform(0.01, 0.03, 4000)
    eps = 0.2 * rng.standard_t(3.0, 4000) + rng.normal(0, 1, 4000) * sd
    assert fit_sigma_eps(eps, sd, nu=3.0) == pytest.approx(0.2, rel=0.08)
    assert fit_sigma_eps(eps, sd) > 1.3 * 0.2  # the normal fit is pulled up by the tail


def test_a_member_that_covers_less_does_not_make_a_bound_where_another_covers(toy_atlas):
    """The identifiable range is the union of the members' ranges: an object only one member reaches is an
    estimate from that member, not a bound."""
    wide = toy_atlas()  # 2pi-40pi
    narrow = dataclasses.replace(toy_atlas(), model="narrow")
    keep = (narrow.omega_n >= 5 * math.pi)
    narrow = dataclasses.replace(narrow, omega_n=narrow.omega_n[keep], mean=narrow.mean[:, :, keep],
                                 spread=narrow.spread[:, :, keep], p_unstable=narrow.p_unstable[:, :, keep])
    fm = ForwardModel("two", (Member(wide, SIGMA), Member(narrow, SIGMA)))
    assert fm.identifiable_range == pytest.approx((2 * math.pi, 40 * math.pi))
    est = identify_atlas(_sweep_from_atlas(wide, 3 * math.pi, 0.7, np.arange(12.0, 38.0, 1.0),
                                           np.random.default_rng(8)), fm)
    assert est.ok and est.bound is None, est.reason
    assert est.omega_n == pytest.approx(3 * math.pi, rel=0.15)
