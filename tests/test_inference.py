"""The atlas posterior (plate_env.inference): the likelihood of stable and unstable probes, pinned term by term."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from plate_env.inference import (
    NU,
    P_MIN,
    SIGMA_MODEL,
    grid_response,
    identify_atlas,
    log_likelihood,
    log_student,
    posterior,
    posterior_grid,
)
from plate_env.probes import ProbeTable

N_OMEGA, N_ALPHA = 41, 7


def test_log_student_is_the_student_t_density_up_to_a_constant():
    rng = np.random.default_rng(0)
    resid = rng.normal(0, 40, 200)
    var = rng.uniform(10, 2000, 200)
    ours = log_student(resid, var)
    ref = stats.t.logpdf(resid, df=NU, scale=np.sqrt(var))
    assert NU == 4.0
    assert np.ptp(ours - ref) < 1e-9  # the same function of (resid, var), shifted by one constant


def test_an_unstable_probe_contributes_the_clipped_instability_probability(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    table = ProbeTable.from_arrays([30.0], 3.0, [0.0], [0.0], [True])
    _, _, p = grid_response(atlas, 3.0, N_OMEGA, N_ALPHA)(30.0)
    expected = np.log(np.clip(p, P_MIN, 1 - P_MIN))
    np.testing.assert_allclose(log_likelihood(atlas, table, N_OMEGA, N_ALPHA), expected, rtol=0, atol=1e-12)
    assert expected.min() == pytest.approx(math.log(P_MIN)) and expected.max() == pytest.approx(math.log(1 - P_MIN))


def test_a_stable_probe_contributes_stability_times_student_t(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    y, e, sigma = 310.0, 6.0, 12.0
    table = ProbeTable.from_arrays([30.0], 3.0, [y], [e], [False])
    mu, s, p = grid_response(atlas, 3.0, N_OMEGA, N_ALPHA)(30.0)
    pc = np.clip(p, P_MIN, 1 - P_MIN)
    expected = np.log1p(-pc) + log_student(y - mu, s ** 2 + e ** 2 + sigma ** 2)
    np.testing.assert_allclose(log_likelihood(atlas, table, N_OMEGA, N_ALPHA, sigma), expected, rtol=0, atol=1e-12)


def test_probes_add_their_log_likelihoods(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    rows = [(18.0, 150.0, 3.0, False), (30.0, 0.0, 0.0, True), (24.0, 400.0, 5.0, False)]
    f, w, se, un = (list(c) for c in zip(*rows, strict=True))
    total = log_likelihood(atlas, ProbeTable.from_arrays(f, 3.0, w, se, un), N_OMEGA, N_ALPHA)
    parts = sum(log_likelihood(atlas, ProbeTable.from_arrays([f], 3.0, [w], [se], [u]), N_OMEGA, N_ALPHA)
                for f, w, se, u in rows)
    np.testing.assert_allclose(total, parts, rtol=0, atol=1e-9)


def test_unstable_probes_move_the_posterior_to_objects_that_go_unstable(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    w, _ = posterior_grid(atlas, N_OMEGA, N_ALPHA)
    stiff = w > 12 * math.pi
    unstable = posterior(atlas, ProbeTable.from_arrays([28.0, 32.0, 36.0], 3.0, [0.0] * 3, [0.0] * 3, [True] * 3),
                         n_omega=N_OMEGA, n_alpha=N_ALPHA)
    assert unstable.marginal_omega()[stiff].sum() > 0.9
    mu, _, _ = atlas.predict(np.array([28.0, 32.0, 36.0]), 3.0, 4 * math.pi, 0.7)
    stable = posterior(atlas, ProbeTable.from_arrays([28.0, 32.0, 36.0], 3.0, mu, [2.0] * 3, [False] * 3),
                       n_omega=N_OMEGA, n_alpha=N_ALPHA)
    assert stable.marginal_omega()[stiff].sum() < 0.1


def test_identify_atlas_reports_its_probes_and_refuses_foreign_amplitudes(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    table = ProbeTable.from_arrays([20.0, 28.0, 32.0], 3.0, [300.0, 0.0, 0.0], [3.0, 0.0, 0.0], [False, True, True])
    est = identify_atlas(table, atlas=atlas)
    assert est.ok and est.method == "atlas" and est.n_probes == 3 and est.n_unstable == 2
    lo, hi = est.omega_n_ci95
    assert lo < est.omega_n_ci68[0] <= est.omega_n <= est.omega_n_ci68[1] < hi
    assert est.posterior is not None and est.posterior.prob.sum() == pytest.approx(1.0)
    bad = identify_atlas(ProbeTable.from_arrays([20.0], 12.0, [100.0]), atlas=atlas)
    assert not bad.ok and "not in this atlas" in bad.reason and bad.n_probes == 1
    empty = identify_atlas(ProbeTable.from_arrays([], [], []), atlas=atlas)
    assert not empty.ok and empty.reason == "no probes"
    assert SIGMA_MODEL == 15.0


def test_posterior_contains_truth_on_data_drawn_from_atlas(toy_atlas):
    atlas = toy_atlas()
    rng = np.random.default_rng(5)
    inside = 0
    for _ in range(20):
        w_true = math.pi * rng.uniform(3, 35)
        a_true = math.radians(rng.uniform(32, 58))
        f = rng.uniform(14, 36, 8)
        mu, s, _ = atlas.predict(f, 3.0, w_true, a_true)
        y = mu + rng.normal(0, 1, f.size) * np.sqrt(s ** 2 + SIGMA_MODEL ** 2)
        post = posterior(atlas, ProbeTable.from_arrays(f, 3.0, y))
        _, _, _, (lo, hi) = post.omega_stats()
        inside += lo <= w_true <= hi
    assert inside >= 17  # 95 % intervals


def test_posterior_passes_its_settings_on_and_stays_finite_with_many_inconsistent_probes(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    f = np.linspace(12.0, 38.0, 40)
    table = ProbeTable.from_arrays(f, 3.0, np.full(f.size, 3000.0), np.full(f.size, 1.0))  # far from every object
    post = posterior(atlas, table, n_omega=N_OMEGA, n_alpha=N_ALPHA)
    assert post.prob.shape == (N_OMEGA, N_ALPHA) and post.alpha.size == N_ALPHA and post.omega_n.size == N_OMEGA
    assert np.all(np.isfinite(post.prob)) and post.prob.sum() == pytest.approx(1.0)
    w, _ = posterior_grid(atlas, N_OMEGA, N_ALPHA)
    assert w[0] == pytest.approx(atlas.omega_n[0]) and w[-1] == pytest.approx(atlas.omega_n[-1])
    mu, _, _ = atlas.predict(np.array([18.0, 24.0]), 3.0, 8 * math.pi, 0.7)
    few = ProbeTable.from_arrays([18.0, 24.0], 3.0, mu + 25.0, [1.0, 1.0])
    tight = identify_atlas(few, atlas=atlas, sigma_model=2.0)
    loose = identify_atlas(few, atlas=atlas, sigma_model=60.0)
    assert tight.omega_n_stderr < loose.omega_n_stderr
    default = posterior(atlas, few, n_omega=N_OMEGA, n_alpha=N_ALPHA)
    assert not np.allclose(posterior(atlas, few, sigma_model=2.0, n_omega=N_OMEGA, n_alpha=N_ALPHA).prob, default.prob)


def test_grid_responses_of_other_grids_are_not_mixed_up_and_are_exact_at_the_range_ends(toy_atlas):
    atlas = toy_atlas()
    small = grid_response(atlas, 3.0, 21, 5)(20.0)
    large = grid_response(atlas, 3.0, 41, 7)(20.0)
    assert small[0].shape == (21, 5) and large[0].shape == (41, 7)
    w, a = posterior_grid(atlas, 21, 5)
    for f in (atlas.f_hz[0], atlas.f_hz[-1]):
        mean, spread, _ = atlas.predict(f, 3.0, w[:, None], a[None, :])
        got = grid_response(atlas, 3.0, 21, 5)(f)
        np.testing.assert_allclose(got[0], mean, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got[1], spread, rtol=1e-9, atol=1e-9)
    below = grid_response(atlas, 3.0, 21, 5)(atlas.f_hz[0] - 5.0)
    np.testing.assert_array_equal(below[0], grid_response(atlas, 3.0, 21, 5)(atlas.f_hz[0])[0])


def test_identify_atlas_reports_every_field(toy_atlas):
    atlas = toy_atlas(unstable_above_pi=10.0)
    table = ProbeTable.from_arrays([20.0, 28.0, 32.0], 3.0, [300.0, 0.0, 0.0], [3.0, 0.0, 0.0], [False, True, True])
    est = identify_atlas(table, atlas=atlas)
    mean, std, ci68, ci95 = est.posterior.omega_stats()
    a_mean, a_std, _, _ = est.posterior.alpha_stats()
    assert (est.omega_n, est.omega_n_stderr, est.omega_n_ci68, est.omega_n_ci95) == (mean, std, ci68, ci95)
    assert (est.alpha, est.alpha_stderr) == (a_mean, a_std) and est.ok is True
    bad = identify_atlas(ProbeTable.from_arrays([20.0, 21.0], 12.0, [1.0, 0.0], unstable=[False, True]), atlas=atlas)
    assert (bad.ok, bad.method, bad.n_probes, bad.n_unstable) == (False, "atlas", 2, 1)
    empty = identify_atlas(ProbeTable.from_arrays([], [], []), atlas=atlas)
    assert (empty.ok, empty.method, empty.n_probes, empty.n_unstable) == (False, "atlas", 0, 0)
