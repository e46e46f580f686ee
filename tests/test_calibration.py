"""Eq. (10) calibration (plate_env.calibration): the regression, its uncertainties and the friction model, pinned
against closed-form least squares."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from plate_env.identify.calibration import (
    Calibration,
    fit_calibration,
    get_calibration,
    linear_fit,
    load_calibrations,
    paper_calibration,
    save_calibrations,
)


def _ols(x, y):
    """Closed-form least squares y = p x + q: p, q, se_p, se_q, cov_pq, R^2, residual std."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    n, xm, ym = len(x), x.mean(), y.mean()
    sxx = np.sum((x - xm) ** 2)
    p = np.sum((x - xm) * (y - ym)) / sxx
    q = ym - p * xm
    ssr = np.sum((y - p * x - q) ** 2)
    s2 = ssr / (n - 2)
    return p, q, math.sqrt(s2 / sxx), math.sqrt(s2 * (1 / n + xm ** 2 / sxx)), -xm * s2 / sxx, \
        1 - ssr / np.sum((y - ym) ** 2), math.sqrt(s2)


def test_linear_fit_is_ordinary_least_squares_with_its_covariance():
    rng = np.random.default_rng(2)
    x = rng.uniform(20, 30, 12)
    y = 5.0 * x - 110.0 + rng.normal(0, 2.0, x.size)
    np.testing.assert_allclose(linear_fit(x, y), _ols(x, y), rtol=1e-9)
    small = linear_fit([1.0, 1.5, 2.0], [0.010, 0.022, 0.029])  # 3 points, x spread exactly 1, tiny y scale
    np.testing.assert_allclose(small, _ols([1.0, 1.5, 2.0], [0.010, 0.022, 0.029]), rtol=1e-9)
    assert math.isnan(linear_fit([1.0, 2.0, 3.0], [4.0, 4.0, 4.0])[5])  # flat y: R^2 undefined, not an error
    for x_bad, y_bad in (([1.0, 2.0], [1.0, 2.0]), ([2.0, 2.0, 2.0], [1.0, 2.0, 3.0])):
        with pytest.raises(ValueError, match=r">= 3 points with different f0, got"):
            linear_fit(x_bad, y_bad)


def test_omega_n_stderr_adds_every_variance_term():
    cal = Calibration("t", "m", 3.0, p1=16.0, q1=-380.0, p1_se=0.9, q1_se=25.0, cov_pq=-22.0, resid_std=7.0)
    f0, sf = 25.0, 0.4
    var = (16.0 * sf) ** 2 + (f0 * 0.9) ** 2 + 25.0 ** 2 + 2 * f0 * (-22.0)
    assert cal.omega_n(f0) == pytest.approx(16.0 * 25.0 - 380.0, rel=1e-15)
    assert cal.omega_n_stderr(f0, sf) == pytest.approx(math.sqrt(var + 7.0 ** 2), rel=1e-12)
    tiny = Calibration("t", "m", 3.0, p1=0.5, q1=0.0, p1_se=0.01, q1_se=0.2, cov_pq=0.001, resid_std=0.3)
    var = (0.5 * 0.1) ** 2 + (2.0 * 0.01) ** 2 + 0.2 ** 2 + 2 * 2.0 * 0.001
    assert tiny.omega_n_stderr(2.0, 0.1) == pytest.approx(math.sqrt(var + 0.3 ** 2), rel=1e-12)
    # a negative covariance larger than the rest leaves only the scatter about the line
    neg = Calibration("t", "m", 3.0, p1=1.0, q1=0.0, p1_se=0.0, q1_se=0.0, cov_pq=-1.0, resid_std=0.5)
    assert neg.omega_n_stderr(3.0, 0.0) == pytest.approx(0.5, rel=1e-15)


def test_omega_n_stderr_covers_the_truth_on_simulated_calibrations():
    """The delta-method error of omega_n_hat = p1 f0 + q1 (f0 with its own error, the line fitted on noisy
    sweeps) holds about 68 % of the time."""
    rng = np.random.default_rng(11)
    f_cal = np.linspace(22.0, 30.0, 12)
    hits = []
    for _ in range(1500):
        w_cal = 5.0 * math.pi * f_cal - 120.0 * math.pi + rng.normal(0, 6.0, f_cal.size)
        cal = fit_calibration(f_cal, w_cal, "t", "m", 3.0)
        f_true = rng.uniform(23.0, 29.0)
        w_true = 5.0 * math.pi * f_true - 120.0 * math.pi + rng.normal(0, 6.0)  # a new object scatters too
        f_seen = f_true + rng.normal(0, 0.3)
        hits.append(abs(cal.omega_n(f_seen) - w_true) <= cal.omega_n_stderr(f_seen, 0.3))
    assert 0.64 <= np.mean(hits) <= 0.72


def test_friction_model_is_least_squares_on_omega_max_and_f0():
    rng = np.random.default_rng(4)
    n = 10
    f0 = rng.uniform(22, 30, n)
    wmax = rng.uniform(400, 700, n)
    alpha = 0.2 + 1e-3 * wmax - 0.01 * f0 + rng.normal(0, 0.01, n)
    cal = fit_calibration(f0, 5 * f0 - 100, "t", "m", 12.0, omega_max_deg_s=wmax, alpha_rad=alpha,
                          provenance={"k": 1})
    design = np.column_stack([np.ones(n), wmax, f0])
    coef, *_ = np.linalg.lstsq(design, alpha, rcond=None)
    assert cal.alpha_coef == pytest.approx(tuple(coef), rel=1e-9)
    assert cal.alpha_resid_std == pytest.approx(math.sqrt(np.sum((alpha - design @ coef) ** 2) / (n - 3)),
                                                rel=1e-9)
    assert cal.alpha(550.0, 26.0) == pytest.approx(coef[0] + coef[1] * 550.0 + coef[2] * 26.0, rel=1e-12)
    assert (cal.n, cal.a_p_deg, cal.provenance) == (10, 12.0, {"k": 1})
    p, q, pse, qse, cpq, r2, rs = linear_fit(f0, 5 * f0 - 100)
    assert (cal.p1, cal.q1, cal.p1_se, cal.q1_se, cal.cov_pq, cal.r2, cal.resid_std) == (p, q, pse, qse, cpq, r2, rs)
    # no friction model without both omega_max and alpha, or with too few sweeps for 3 coefficients + scatter
    for kw in ({}, {"omega_max_deg_s": wmax}, {"alpha_rad": alpha}):
        plain = fit_calibration(f0, 5 * f0 - 100, "t", "m", 3.0, **kw)
        assert plain.alpha_coef is None and plain.alpha_resid_std == 0.0 and plain.alpha(500.0, 25.0) is None
    three = fit_calibration(f0[:3], 5 * f0[:3] - 100, "t", "m", 3.0, omega_max_deg_s=wmax[:3], alpha_rad=alpha[:3])
    assert three.alpha_coef is None
    four = fit_calibration(f0[:4], 5 * f0[:4] - 100, "t", "m", 3.0, omega_max_deg_s=wmax[:4], alpha_rad=alpha[:4])
    assert four.alpha_coef is not None and four.alpha_resid_std > 0


def test_paper_coefficients_in_rad_per_s():
    for a, (p1, q1) in ((3, (5.30, -121.62)), (12.0, (5.65, -64.51))):
        cal = paper_calibration(a)
        assert (cal.physics, cal.model, cal.a_p_deg) == ("paper", "paper", float(a))
        assert isinstance(cal.a_p_deg, float) and "Section 6.1" in cal.provenance["source"]
        assert (cal.p1, cal.q1) == pytest.approx((p1 * math.pi, q1 * math.pi), rel=1e-15)
    with pytest.raises(ValueError, match=r"only for A_p in \[3.0, 12.0\] deg, not 5"):
        paper_calibration(5)


def test_saved_calibrations_are_found_by_key_and_missing_ones_are_named(tmp_path):
    path = tmp_path / "cal.json"
    a = fit_calibration([22.0, 25.0, 28.0, 30.0], [60.0, 75.0, 92.0, 100.0], "tilelink", "rigid", 3.0)
    b = Calibration("tilelink", "rigid", 12.0, p1=1.0, q1=2.0, r2=0.5)
    save_calibrations([a, b], path)
    text = path.read_text()
    assert text.endswith("}\n") and list(json.loads(text)) == ["tilelink/rigid/12", "tilelink/rigid/3"]
    assert json.loads(text)["tilelink/rigid/12"]["alpha_coef"] is None
    assert text == json.dumps(json.loads(text), indent=1, sort_keys=True) + "\n"
    assert get_calibration("tilelink", "rigid", 3, path=path) == a
    assert get_calibration("tilelink", "rigid", 12.0, path=path) == b
    assert get_calibration("paper", "anything", 3.0, path=path) == paper_calibration(3.0)
    with pytest.raises(ValueError, match=r"no calibration for tilelink/pointmass/3; available: "
                                         r"\['tilelink/rigid/12', 'tilelink/rigid/3'\]"):
        get_calibration("tilelink", "pointmass", 3.0, path=path)
    empty = tmp_path / "empty.json"
    empty.write_text("{}")
    with pytest.raises(ValueError, match="available: none"):
        get_calibration("tilelink", "rigid", 3.0, path=empty)


def test_paper_calibration_units():
    cal = paper_calibration(3)
    assert cal.omega_n(25.1) == pytest.approx((5.30 * 25.1 - 121.62) * math.pi)
    with pytest.raises(ValueError, match="A_p"):
        paper_calibration(5)


def test_calibration_fit_and_round_trip(tmp_path):
    f0 = np.array([23.0, 24.5, 26.0, 27.5, 29.0])
    w = 5.0 * math.pi * f0 - 110 * math.pi
    cal = fit_calibration(f0, w, "tilelink", "pointmass", 3.0, omega_max_deg_s=[500, 550, 600, 650, 700],
                          alpha_rad=np.radians([30, 40, 35, 50, 45]), provenance={"note": "test"})
    assert cal.p1_pi == pytest.approx(5.0) and cal.q1_pi == pytest.approx(-110.0) and cal.r2 == pytest.approx(1.0)
    path = tmp_path / "cal.json"
    save_calibrations([cal], path)
    back = load_calibrations(path)["tilelink/pointmass/3"]
    assert back == cal and back.provenance == {"note": "test"}


def test_shipped_calibration_has_provenance():
    cals = load_calibrations()
    cal = cals["tilelink/pointmass/3"]
    assert isinstance(cal, Calibration) and cal.n >= 20
    assert cal.provenance["window"] == "first_hump" and "dt_s" in cal.provenance
