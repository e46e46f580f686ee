"""The Lorentzian fit, Eq. (9) (plate_env.fitting): the first-hump window rule by rule, the fit's values and
their reporting, pinned on hand-made curves."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.fitting import DEFAULT_DROP, RISE_STEP, first_hump_mask, fit_lorentzian, fit_results, lorentzian
from plate_env.physics.base import ProbeResult, ProbeSpec


def _mask(y, unstable=(), f=None):
    f = np.arange(10.0, 10.0 + len(y)) if f is None else np.asarray(f, float)
    y = np.asarray(y, float)
    usable = ~np.isin(f, unstable)
    return dict(zip(f.tolist(), first_hump_mask(f, y, usable).tolist(), strict=True))


RAMP = [10.0 * k for k in range(1, 11)]  # 10 .. 100 deg/s at 10 .. 19 Hz: straight, so the curve's roughness is 0


def test_one_unstable_probe_does_not_end_the_hump_two_do():
    # top 100 at 19 Hz, one unstable probe at 20, then 90 at 21 (10 % down): that drop ends the hump, included
    # (later probes stay below twice the top, so the run is not on the hump's foot)
    m = _mask(RAMP + [0, 90, 150, 150], unstable=(20.0,))
    assert m[19.0] and m[21.0] and not m[22.0] and not m[23.0]
    # two unstable probes in a row past the top end it although later probes stay at the top (no drop)
    m = _mask(RAMP + [100, 0, 0, 100, 100, 100], unstable=(21.0, 22.0))
    assert m[20.0] and not any(m[f] for f in (23.0, 24.0, 25.0))
    m = _mask(RAMP + [100, 0, 0, 0, 100, 100], unstable=(21.0, 22.0, 23.0))
    assert m[20.0] and not m[24.0]


def test_unstable_probes_before_any_stable_one_do_not_end_the_hump():
    m = _mask([0, 0] + RAMP + [80], unstable=(10.0, 11.0))
    assert all(m[f] for f in (17.0, 18.0, 19.0, 20.0, 21.0, 22.0))


def test_rising_into_an_unstable_run_bridges_it_exactly_above_the_rise_step():
    assert RISE_STEP == 0.1
    # 90 -> 100 is a rise of exactly RISE_STEP of the last probe: not "still rising", the run ends the window
    m = _mask(RAMP + [0, 0, 150, 160], unstable=(20.0, 21.0))
    assert m[19.0] and not m[22.0] and not m[23.0]
    # 89 -> 100 is more: the run is bridged
    m = _mask(RAMP[:8] + [89.0, 100.0] + [0, 0, 150, 160], unstable=(20.0, 21.0))
    assert m[22.0] and m[23.0]


def test_a_probe_exactly_at_the_drop_does_not_end_the_hump():
    assert DEFAULT_DROP == 0.05
    m = _mask(RAMP + [95, 97, 80, 100])  # 95 is not below 95 % of 100; 80 is
    assert m[20.0] and m[21.0] and m[22.0] and not m[23.0]
    assert not m[10.0] and not m[12.0] and m[13.0]  # below / at the floor, 0.4 x 100


def _results(f, y, se, unstable, b_p_mm=3.0):
    obj = pe.preset("cheese")
    return [ProbeResult(spec=ProbeSpec(obj, pe.PlateMotion.from_paper(float(fi), 3.0, b_p_mm)), omega_b_deg_s=float(w),
                        stderr_deg_s=float(s), unstable=bool(u), reason="slipped" if u else None, sim_s=1.7,
                        wall_s=0.0, periods_measured=25) for fi, w, s, u in zip(f, y, se, unstable, strict=True)]


def test_fit_results_fits_the_probes_own_numbers():
    rng = np.random.default_rng(8)
    f = np.arange(14.0, 36.0, 1.0)
    se = rng.uniform(2.0, 30.0, f.size)
    y = lorentzian(f, 520.0, 24.0, 4.0) + rng.normal(0, se)
    unstable = f >= 33
    y[unstable] = 0.0
    res = _results(f, y, se, unstable)
    for kw in ({}, {"window": "all"}, {"weighted": False}, {"drop": 0.2, "floor": 0.1}):
        got = fit_results(res, **kw)
        want = fit_lorentzian(f, y, None if kw.get("weighted") is False else se, unstable,
                              window=kw.get("window", "first_hump"), drop=kw.get("drop", DEFAULT_DROP),
                              floor=kw.get("floor", 0.4))
        assert got.ok and (got.f0, got.b, got.omega_max, got.stderr) == (want.f0, want.b, want.omega_max, want.stderr)
        assert got.n_unstable == int(unstable.sum())
    weighted, plain = fit_results(res), fit_results(res, weighted=False)
    assert weighted.f0 != plain.f0


def test_prediction_and_report_of_a_clockwise_sweep():
    f = np.arange(14.0, 36.0, 1.0)
    fit = fit_lorentzian(f, -lorentzian(f, 500.0, 25.0, 4.0), window="all")
    assert fit.ok and fit.sign == -1.0 and fit.omega_max == pytest.approx(500.0, rel=1e-9)
    np.testing.assert_allclose(fit.predict(np.array([20.0, 25.0])), -lorentzian(np.array([20.0, 25.0]), 500.0,
                                                                                  25.0, 4.0), rtol=1e-8)
    assert fit.to_dict() == {"ok": True, "reason": None, "omega_max_deg_s": fit.omega_max, "f0_hz": fit.f0,
                             "b_hz": fit.b, "omega_max_stderr_deg_s": fit.stderr[0], "f0_stderr_hz": fit.stderr[1],
                             "b_stderr_hz": fit.stderr[2], "r2": fit.r2, "n_used": 22, "n_unstable": 0}
    assert fit.f0_stderr == fit.stderr[1]


def test_overflowing_data_are_refused_not_fitted_with_a_nan_r2():
    """Found by the robustness property test while the mutation tool ran it many times: frequencies and rates
    near 1e16-1e285 fitted "ok" with R^2 = NaN (the spread of the data overflows)."""
    f = [1.025, 5.39e-213, -1.55e251, 1.025, 11.86, -9.05e-45, -1.9, 4.77e16, -1.03e-145, -5.61e16, -3.15e16,
         -4.36e-46]
    w = [5.39e-213, -4.2e-237, -1.18e-38, 6.73e16, 4.24e266, 3.38e181, -4.99e32, math.inf, -4.38e21, 8.34e285,
         5.44e16, 5.2e16]
    unstable = [True, True, True, False, False, True, False, False, True, True, False, False]
    with np.errstate(all="ignore"):
        fit = fit_lorentzian(f, w, w, unstable, window="all")
    assert not fit.ok and fit.reason
