"""Fitting the coherent discrepancy (plate_env.inference): exactly, on the posteriors themselves, and between models,
where the objects of one pair of models are not independent evidence of how far models lie apart."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.forward import PAD_MAX_LOG, ForwardModel, Member
from plate_env.identify.inference import (
    family_discrepancy,
    fit_discrepancy,
    fit_discrepancy_exact,
    identify_atlas,
    truth_log_density,
)


def _sweep(atlas, w, a, f, rng, sigma=5.0):
    mu, s, _ = atlas.predict(f, 3.0, w, a)
    return ProbeTable.from_arrays(f, 3.0, mu + rng.normal(0, 1, f.size) * np.sqrt(s ** 2 + sigma ** 2),
                                  np.zeros(f.size))


def _fm(atlas, **kw) -> ForwardModel:
    return ForwardModel("toy", (Member(atlas, 5.0),), **kw)


@pytest.mark.parametrize("sigma, nu", [(0.15, math.inf), (0.1, 2.0), (0.2, 1.0)])
def test_truth_log_density_is_the_density_the_forward_model_reports(toy_atlas, sigma, nu):
    """The likelihood fit_discrepancy_exact maximises is the density of the posterior the forward model with that
    discrepancy reports: smoothing the members' own marginal of the model without it reproduces it."""
    atlas = toy_atlas()
    table = _sweep(atlas, 9 * math.pi, 0.8, np.arange(14.0, 36.0, 2.0), np.random.default_rng(1))
    zero = identify_atlas(table, _fm(atlas)).posterior
    post = identify_atlas(table, _fm(atlas, sigma_eps=sigma, eps_nu=nu)).posterior
    lw = np.log(post.omega_n)
    dens = post.marginal_omega() / (post.marginal_omega().sum() * (lw[1] - lw[0]))
    for w in (6 * math.pi, 9 * math.pi, 13 * math.pi):
        ref = math.log(float(np.interp(math.log(w), lw, dens)))
        assert truth_log_density(zero, w, sigma, nu) == pytest.approx(ref, abs=0.02)


def test_fit_discrepancy_exact_recovers_a_known_discrepancy_and_its_tails(toy_atlas):
    """Objects whose data sit at omega_n shifted by exp(eps), eps Student-t (nu 2, scale 0.12): the exact fit finds
    the scale and prefers heavy tails to a normal; with no shift it finds none worth its tails."""
    atlas = toy_atlas()
    rng = np.random.default_rng(4)
    f = np.arange(12.0, 38.0, 2.0)
    zero = _fm(atlas)

    def posts(scale):
        out = []
        for _ in range(150):
            w = math.exp(rng.uniform(math.log(6 * math.pi), math.log(16 * math.pi)))
            shift = scale * rng.standard_t(2.0) if scale else 0.0
            shifted = float(np.clip(w * math.exp(shift), 2.2 * math.pi, 38 * math.pi))
            out.append((w, identify_atlas(_sweep(atlas, shifted, math.radians(rng.uniform(33, 57)), f, rng),
                                          zero).posterior))
        return zip(*out, strict=True)

    nu, sigma = fit_discrepancy_exact(*posts(0.12))
    assert 0.08 < sigma < 0.18 and nu <= 5.0, (nu, sigma)
    nu0, sigma0 = fit_discrepancy_exact(*posts(0.0))
    assert sigma0 < 0.03, (nu0, sigma0)


def test_fit_discrepancy_exact_refuses_mismatched_inputs(toy_atlas):
    atlas = toy_atlas()
    post = identify_atlas(_sweep(atlas, 9 * math.pi, 0.8, np.arange(14.0, 36.0, 2.0),
                                 np.random.default_rng(1)), _fm(atlas)).posterior
    with pytest.raises(ValueError, match="2 true values for 1 posteriors"):
        fit_discrepancy_exact([1.0, 2.0], [post])


def _families(rng, k, tau, n_obj=20, scatter=0.05):
    """K models whose readings of one object differ by model offsets mu ~ N(0, tau^2): pairs[(a, b)] are model a's
    objects identified by model b (eps = mu_a - mu_b + object scatter), posterior sd 0.03."""
    mu = rng.normal(0, tau, k)
    pairs = {(str(a), str(b)): (mu[a] - mu[b] + rng.normal(0, scatter, n_obj), np.full(n_obj, 0.03))
             for a in range(k) for b in range(k) if a != b}
    return mu, pairs


def _interval(disc, rng, n=4000):
    """The 68 and 95 % central intervals of offset + scatter, by sampling."""
    draws = disc.offset_sigma * rng.standard_t(disc.offset_nu, n)
    draws += disc.sigma * (rng.standard_t(disc.nu, n) if math.isfinite(disc.nu) else rng.standard_normal(n))
    return np.percentile(draws, [16, 84, 2.5, 97.5])


def test_family_discrepancy_holds_its_coverage_on_a_model_left_out_where_the_object_level_fit_does_not():
    """Simulation-based calibration across models: three models drawn with random offsets, one left out, the
    discrepancy estimated from the other two. The left-out model's objects read by one of the pool's models are
    off by the offset between them; the family-level Student-t (one degree of freedom from two models) holds it at
    least at its 68 / 95 % rates over 600 draws (a little above: the offset observed between the two pooled models
    shares one of them with the new one), while one t fitted to every object as independent evidence (the fit this
    replaced) misses far more often than it promises."""
    rng = np.random.default_rng(13)
    hits = {"family": [], "objects": []}
    for _ in range(600):
        mu, pairs = _families(rng, 3, tau=0.3)
        rest = {p: v for p, v in pairs.items() if "2" not in p}
        eps_out = mu[2] - mu[rng.integers(0, 2)] + rng.normal(0, 0.05)
        disc = family_discrepancy(rest)
        assert disc.offset_nu == 1.0
        lo68, hi68, lo95, hi95 = _interval(disc, rng)
        hits["family"].append((lo68 <= eps_out <= hi68, lo95 <= eps_out <= hi95))
        nu0, s0 = fit_discrepancy(np.concatenate([v[0] for v in rest.values()]),
                                  np.concatenate([v[1] for v in rest.values()]))
        half95 = (stats.t.ppf(0.975, nu0) if math.isfinite(nu0) else 1.96) * math.hypot(s0, 0.03)
        hits["objects"].append(abs(eps_out) <= half95)
    c68, c95 = np.mean(hits["family"], axis=0)
    assert 0.62 <= c68 <= 0.85 and c95 >= 0.93, (c68, c95)
    assert np.mean(hits["objects"]) < 0.85


def test_family_discrepancy_uses_k_minus_one_degrees_of_freedom_and_refuses_one_model():
    rng = np.random.default_rng(2)
    _, pairs = _families(rng, 4, tau=0.2)
    disc = family_discrepancy(pairs)
    assert disc.offset_nu == 3.0 and disc.models == ("0", "1", "2", "3")
    assert disc.offset_sigma == pytest.approx(math.sqrt(np.mean([np.mean(v[0]) ** 2 for v in pairs.values()])))
    assert disc.sigma == pytest.approx(math.sqrt(0.05 ** 2 - 0.03 ** 2), rel=0.35)  # the objects' own scatter
    with pytest.raises(ValueError, match="no pairs"):
        family_discrepancy({})


def test_a_cauchy_discrepancy_pads_the_grid_at_most_by_its_cap(toy_atlas):
    """A discrepancy whose 99.5 % quantile lies beyond a factor 1000 pads the grid by that factor only, and the
    member's likelihood is computed on its own range only (the padding adds no probe work)."""
    atlas = toy_atlas()
    fm = _fm(atlas, sigma_eps=0.5, eps_nu=1.0)
    w, _ = fm.grid(41, 7)
    lo, hi = fm.omega_range
    assert math.log(lo / w[0]) == pytest.approx(PAD_MAX_LOG, abs=math.log(w[1] / w[0]))
    assert math.log(w[-1] / hi) == pytest.approx(PAD_MAX_LOG, abs=math.log(w[1] / w[0]))
    table = _sweep(atlas, 9 * math.pi, 0.8, np.arange(14.0, 36.0, 2.0), np.random.default_rng(1))
    est = identify_atlas(table, fm)
    assert est.omega_n_ci95[0] < est.omega_n < est.omega_n_ci95[1]
    narrow = identify_atlas(table, dataclasses.replace(fm, sigma_eps=0.0))
    assert est.omega_n == pytest.approx(narrow.omega_n, rel=0.05)


def test_an_offset_between_models_widens_the_posterior_as_its_sum_with_the_scatter(toy_atlas):
    """The posterior is smoothed by the offset and the scatter in turn: with two normal parts its log-omega spread
    is that of one normal of their quadrature sum (and the model without either is narrower than both)."""
    atlas = toy_atlas()
    table = _sweep(atlas, 9 * math.pi, 0.8, np.arange(14.0, 36.0, 2.0), np.random.default_rng(1))
    two = identify_atlas(table, _fm(atlas, sigma_eps=0.12, offset_sigma=0.16))
    one = identify_atlas(table, _fm(atlas, sigma_eps=0.2))
    bare = identify_atlas(table, _fm(atlas))

    def width(e):
        return math.log(e.omega_n_ci95[1] / e.omega_n_ci95[0])

    assert width(two) == pytest.approx(width(one), rel=0.03)
    assert width(bare) < 0.5 * width(two)
    with pytest.raises(ValueError, match="offset_sigma"):
        _fm(atlas, offset_sigma=-0.1)
    with pytest.raises(ValueError, match="offset_nu"):
        _fm(atlas, offset_sigma=0.1, offset_nu=0.5)


# ----------------------------------------------------------------------------------------- the paper's method
def test_offset_intervals_are_the_quantiles_of_the_normal_plus_the_offset():
    from plate_env.identify import offset_intervals

    rng = np.random.default_rng(3)
    for se, scale, nu in [(5.0, 5.0, 2.0), (1.0, 10.0, 1.0), (10.0, 1.0, 3.0)]:
        d = se * rng.standard_normal(400_000) + scale * rng.standard_t(nu, 400_000)
        ci68, ci95, stderr = offset_intervals(500.0, se, scale, nu)
        q = np.percentile(d, [2.5, 16, 84, 97.5]) + 500.0
        assert ci68 == pytest.approx((q[1], q[2]), rel=0.01) and ci95 == pytest.approx((q[0], q[3]), rel=0.02)
        assert stderr == pytest.approx((ci68[1] - ci68[0]) / 2)
    assert offset_intervals(500.0, 3.0, 0.0, math.inf)[2] == pytest.approx(3.0)


def test_a_line_pooled_over_models_keeps_their_lines_and_its_interval_holds_on_a_model_left_out():
    """Simulation-based calibration of the paper's Eq. (10) across models: three models whose lines differ at
    random (slope and intercept), a pooled line from two, the third's objects read through it. Its intervals (the
    scatter about each model's own line plus the offset between models, Student-t with one degree of freedom) hold
    the truth at least at their rates over 300 draws; the pooled residual alone (one normal) does not."""
    from plate_env.identify import offset_intervals
    from plate_env.identify.calibration import fit_calibration

    rng = np.random.default_rng(21)
    hits, naive = [], []
    for _ in range(300):
        lines = [(2.0 + rng.normal(0, 0.3), 40.0 + rng.normal(0, 8.0)) for _ in range(3)]  # omega_n > 0

        def points(m, n=30, lines=lines):
            f0 = rng.uniform(18.0, 30.0, n)
            return f0, lines[m][0] * f0 + lines[m][1] + rng.normal(0, 2.0, n)

        (fa, wa), (fb, wb) = points(0), points(1)
        cal = fit_calibration(np.r_[fa, fb], np.r_[wa, wb], "toy", "toy", 3.0, groups=["a"] * 30 + ["b"] * 30)
        assert cal.offset_nu == 1.0 and len(cal.model_lines) == 2
        f0, w = points(2, 1)
        x = cal.omega_n(float(f0[0]))
        ci68, ci95, _ = offset_intervals(x, cal.resid_std, cal.offset_scale(float(f0[0])), cal.offset_nu)
        hits.append((ci68[0] <= w[0] <= ci68[1], ci95[0] <= w[0] <= ci95[1]))
        pooled = fit_calibration(np.r_[fa, fb], np.r_[wa, wb], "toy", "toy", 3.0)
        assert pooled.model_lines == () and pooled.offset_scale(25.0) == 0.0
        naive.append(abs(w[0] - pooled.omega_n(float(f0[0]))) <= 1.96 * pooled.resid_std)
    c68, c95 = np.mean(hits, axis=0)
    assert c68 >= 0.62 and c95 >= 0.93, (c68, c95)
    assert np.mean(naive) < 0.85
    with pytest.raises(ValueError, match="at least two models"):
        dataclasses.replace(cal, model_lines=((1.0, 2.0),))
