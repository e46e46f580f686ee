"""Lorentzian fitter, Eq. (10) calibration, response atlas, posterior, identification API, lab CSV."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from plate_env.atlas import Atlas, atlas_from_repeats, load_atlas
from plate_env.calibration import (
    Calibration,
    fit_calibration,
    load_calibrations,
    paper_calibration,
    save_calibrations,
)
from plate_env.cli import main
from plate_env.fitting import fit_lorentzian, lorentzian
from plate_env.identify import identify
from plate_env.inference import SIGMA_MODEL, posterior
from plate_env.probes import CsvError, ProbeTable, read_lab_csv

F = np.arange(10.0, 40.01, 1.5)


def test_exact_recovery_noiseless():
    fit = fit_lorentzian(F, lorentzian(F, 600.0, 25.1, 5.1), window="all")
    assert fit.ok and fit.r2 == pytest.approx(1.0)
    assert (fit.omega_max, fit.f0, fit.b) == pytest.approx((600.0, 25.1, 5.1), rel=1e-8)


def test_noisy_recovery_one_sigma_coverage_near_68_percent():
    rng = np.random.default_rng(1)
    hits = []
    for _ in range(400):
        f0 = rng.uniform(20, 32)
        y = lorentzian(F, 600.0, f0, rng.uniform(3.5, 6.5)) + rng.normal(0, 15.0, F.size)
        fit = fit_lorentzian(F, y, np.full(F.size, 15.0), window="all")
        assert fit.ok
        hits.append(abs(fit.f0 - f0) <= fit.f0_stderr)
    assert 0.62 <= np.mean(hits) <= 0.75


def test_agrees_with_lmfit_lorentzian_model():
    lmfit = pytest.importorskip("lmfit")
    rng = np.random.default_rng(3)
    y = lorentzian(F, 550.0, 26.0, 4.5) + rng.normal(0, 12.0, F.size)
    ours = fit_lorentzian(F, y, window="all")
    model = lmfit.models.LorentzianModel()
    res = model.fit(y, model.guess(y, x=F), x=F)
    height = res.params["amplitude"].value / (math.pi * res.params["sigma"].value)
    assert ours.f0 == pytest.approx(res.params["center"].value, rel=1e-5)
    assert ours.b == pytest.approx(res.params["sigma"].value, rel=1e-4)
    assert ours.omega_max == pytest.approx(height, rel=1e-4)
    assert ours.stderr[1] == pytest.approx(res.params["center"].stderr, rel=1e-2)


@pytest.mark.parametrize("f, y", [([20.0, 25.0], [300.0, 500.0]), (F, np.full(F.size, 200.0)),
                                  ([20, 21, 22], [1, 2, 3])])
def test_cannot_fit_is_a_result_not_an_exception(f, y):
    fit = fit_lorentzian(f, y, window="all")
    assert not fit.ok and fit.reason


def test_fit_to_the_foot_of_a_hump_is_refused():
    # a rising foot, as in a 33pi rigid-tile sweep whose rising edge slipped: without the peak-height rule a narrow
    # Lorentzian's tail fits these four points with f0 = 30.9 Hz and omega_max = 1.9e9 deg/s
    fit = fit_lorentzian([14.0, 15.0, 16.0, 17.0], [60.0, 70.0, 76.0, 90.0], window="all")
    assert not fit.ok and "foot" in fit.reason
    ok = fit_lorentzian(F, lorentzian(F, 600.0, 25.0, 5.0), window="all")
    assert ok.ok and ok.omega_max == pytest.approx(600.0, rel=1e-6)


def test_unstable_probes_are_excluded_and_counted():
    y = lorentzian(F, 600.0, 25.0, 5.0)
    unstable = F > 33
    y_bad = np.where(unstable, 0.0, y)
    fit = fit_lorentzian(F, y_bad, unstable=unstable, window="all")
    assert fit.ok and fit.n_unstable == int(unstable.sum())
    assert fit.f0 == pytest.approx(25.0, rel=1e-6)


def test_first_hump_window_stops_at_dip_and_unstable_runs():
    f = np.arange(14.0, 40.0, 1.0)
    y = np.where(f <= 26, lorentzian(f, 500.0, 25.0, 4.0), 300.0 + 15 * (f - 26))
    fit = fit_lorentzian(f, y)
    assert fit.ok and fit.f0 == pytest.approx(25.0, abs=0.6)
    assert not fit.used[f > 28].any()


def test_unstable_run_on_the_rising_edge_does_not_end_the_first_hump():
    f = np.arange(14.0, 35.0, 1.0)
    y = 60.0 + lorentzian(f, 600.0, 27.0, 4.0)  # 159 and 180 deg/s at 18 and 19 Hz: still rising > 10 % a probe
    unstable = (f == 20) | (f == 21) | (f >= 30)
    fit = fit_lorentzian(f, y, unstable=unstable)
    assert fit.ok and fit.used[(f >= 22) & (f <= 28)].all()
    assert fit.f0 == pytest.approx(27.0, abs=0.5)
    # past the top (flat into the run) an unstable run still ends the window: a later climb is not fitted
    y2 = np.where(f <= 28, lorentzian(f, 600.0, 26.0, 4.0), 800.0)
    unstable2 = (f == 29) | (f == 30)
    fit2 = fit_lorentzian(f, y2, unstable=unstable2)
    assert fit2.ok and not fit2.used[f > 30].any()


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


def _toy_atlas() -> Atlas:
    f = np.arange(10.0, 41.0, 2.0)
    w = np.geomspace(2, 40, 7) * math.pi
    a = np.radians([30.0, 40.0, 50.0, 60.0])
    ff, ww, aa = np.meshgrid(f, w, a, indexing="ij")
    f0 = 22 + 6 * np.log(ww / (2 * math.pi)) / np.log(20) - 4 * (aa - 0.7)
    mean = lorentzian(ff, 400 + 200 * np.log(ww / math.pi) / 4, f0, 4.5)
    rng = np.random.default_rng(0)
    reps = mean[:, None, :, :, None] + rng.normal(0, 5, (*mean.shape[:1], 1, *mean.shape[1:], 3))
    return atlas_from_repeats("toy", "toy", f, [3.0], w, a, reps, np.full(reps.shape, 2.0),
                              np.zeros(reps.shape, bool), {"toy": True})


def test_atlas_interpolation_exact_at_grid_points_and_round_trip(tmp_path):
    atlas = _toy_atlas()
    i, k, j = 5, 3, 2
    mean, spread, pu = atlas.predict(atlas.f_hz[i], 3.0, atlas.omega_n[k], atlas.alpha[j])
    assert mean == pytest.approx(atlas.mean[i, 0, k, j], rel=1e-12)
    assert spread == pytest.approx(atlas.spread[i, 0, k, j], rel=1e-12)
    path = tmp_path / "atlas.npz"
    atlas.save(path)
    back = Atlas.load(path)
    np.testing.assert_allclose(back.mean, atlas.mean, rtol=1e-6)
    assert back.provenance == {"toy": True}
    with pytest.raises(ValueError, match="not in this atlas"):
        atlas.predict(20.0, 12.0, 30.0, 0.7)


def test_posterior_contains_truth_on_data_drawn_from_atlas():
    atlas = _toy_atlas()
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


def test_identify_lorentz_combines_amplitudes_by_inverse_variance():
    f = np.arange(10.0, 40.01, 2.0)
    cals = {3.0: paper_calibration(3), 12.0: paper_calibration(12)}
    t3 = ProbeTable.from_arrays(f, 3.0, lorentzian(f, 600, 25.1, 5.1), np.full(f.size, 5.0))
    t12 = ProbeTable.from_arrays(f, 12.0, lorentzian(f, 380, 13.0, 3.0), np.full(f.size, 5.0))
    both = ProbeTable(*(np.concatenate([getattr(t3, k), getattr(t12, k)]) for k in
                        ("f_p_hz", "a_p_deg", "omega_b_deg_s", "stderr_deg_s", "unstable")))
    e3 = identify(t3, calibrations=cals)
    e12 = identify(t12, calibrations=cals)
    eb = identify(both, calibrations=cals)
    assert e3.ok and e12.ok and eb.ok
    w3, w12 = 1 / e3.omega_n_stderr ** 2, 1 / e12.omega_n_stderr ** 2
    assert eb.omega_n == pytest.approx((w3 * e3.omega_n + w12 * e12.omega_n) / (w3 + w12))
    assert eb.omega_n_stderr < min(e3.omega_n_stderr, e12.omega_n_stderr)


def test_identify_reports_cannot_fit():
    est = identify(ProbeTable.from_arrays([20.0, 25.0], 3.0, [100.0, 200.0]), physics="paper")
    assert not est.ok and "at least 4" in est.reason
    with pytest.raises(ValueError, match="unknown identification method"):
        identify(ProbeTable.from_arrays([20.0], 3.0, [1.0]), method="magic")


def test_shipped_atlas_loads_and_identifies_one_sided_mixed_data():
    atlas = load_atlas("tilelink", "pointmass")
    w_true, a_true = 17 * math.pi, math.radians(45)
    f = np.array([12.0, 16.0, 19.0, 21.0])  # rising side only
    mu3, _, _ = atlas.predict(f, 3.0, w_true, a_true)
    mu12, _, _ = atlas.predict(f[:2], 12.0, w_true, a_true)
    table = ProbeTable.from_arrays(np.r_[f, f[:2]], np.r_[[3.0] * 4, [12.0] * 2], np.r_[mu3, mu12])
    est = identify(table, method="atlas")
    assert est.ok and est.omega_n_ci95[0] <= w_true <= est.omega_n_ci95[1]


def _write(tmp_path, text):
    p = tmp_path / "lab.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, message", [
    ("f_p_hz,omega\n10,1\n", "missing column(s) omega_b_deg_s"),
    ("f_p_hz,omega_b_deg_s\n10,abc\n", "line 2, column omega_b_deg_s"),
    ("f_p_hz,omega_b_deg_s\n10,1\n-3,4\n", "line 3, column f_p_hz"),
    ("f_p_hz,omega_b_deg_s\n10,1,2\n", "line 2: 3 fields"),
    ("f_p_hz,omega_b_deg_s,stderr_deg_s\n10,1,nan\n", "line 2, column stderr_deg_s"),
    ("", "empty file"),
    ("f_p_hz,omega_b_deg_s\n", "no data rows"),
])
def test_csv_errors_name_line_and_column(tmp_path, text, message):
    with pytest.raises(CsvError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_lab_csv(_write(tmp_path, text), a_p_deg=3.0)


def test_csv_needs_an_amplitude(tmp_path):
    with pytest.raises(CsvError, match="--amp"):
        read_lab_csv(_write(tmp_path, "f_p_hz,omega_b_deg_s\n10,1\n"))


def test_cli_fit_json_and_plot(tmp_path, capsys):
    f = np.arange(8.0, 18.01, 1.0)
    y = lorentzian(f, 380.0, 13.0, 2.5)
    p = _write(tmp_path, "f_p_hz,omega_b_deg_s,stderr_deg_s\n" + "".join(f"{a},{b},5\n" for a, b in zip(f, y,
                                                                                                   strict=True)))
    png = tmp_path / "fit.png"
    assert main(["fit", str(p), "--amp", "12", "--physics", "paper", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] and out["fits"]["12"]["f0_hz"] == pytest.approx(13.0, rel=1e-3)
    assert out["omega_n_rad_s"] == pytest.approx(paper_calibration(12).omega_n(13.0), rel=1e-3)
    assert png.stat().st_size > 5000
    assert main(["fit", str(tmp_path / "missing.csv"), "--amp", "3"]) == 2
