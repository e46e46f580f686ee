"""The camera model (plate_env.camera): frames of the yaw at a frame rate with angle noise, omega_B by a
least-squares slope, sign-normalised by sign(A_p * B_p)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.core.probe import ProbeResult, ProbeSpec, YawTrace
from plate_env.physics.camera import camera_omega_b


def _result(rate_deg_s: float, a_p_deg: float = 3.0, b_p_mm: float = 3.0, trace: bool = True,
            periods: int | None = None, measure_s: float = 1.0) -> ProbeResult:
    """A probe whose disc turns at exactly ``rate_deg_s`` (signed, as the simulation reports it)."""
    spec = ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(20.0, a_p_deg, b_p_mm), measure_s=measure_s)
    t = np.arange(0.0, spec.duration_s + 5e-4, 1e-3)
    tr = YawTrace(t=t, yaw=0.3 + math.radians(rate_deg_s) * t, centre_u=0 * t, centre_v=0 * t) if trace else None
    return ProbeResult(spec=spec, omega_b_deg_s=rate_deg_s, stderr_deg_s=1.5, unstable=False, reason=None,
                       sim_s=spec.duration_s, wall_s=0.0,
                       periods_measured=spec.n_periods if periods is None else periods, trace=tr)


@pytest.mark.parametrize("a_p_deg, b_p_mm, turn, seen", [(3.0, 3.0, 250.0, 250.0), (3.0, -3.0, -250.0, 250.0),
                                                          (-3.0, -3.0, 250.0, 250.0), (-3.0, 3.0, -250.0, 250.0),
                                                          (3.0, -3.0, 40.0, -40.0)])
def test_slope_is_exact_without_noise_and_sign_normalised(a_p_deg, b_p_mm, turn, seen):
    rng = np.random.default_rng(0)
    omega, se = camera_omega_b(_result(turn, a_p_deg, b_p_mm), rng, fps=30.0, angle_noise_deg=0.0)
    assert omega == pytest.approx(seen, rel=1e-9)
    assert se < 1e-6


@pytest.mark.parametrize("b_p_mm", [3.0, -3.0])
def test_without_frames_the_probe_value_is_returned_sign_normalised(b_p_mm):
    rng = np.random.default_rng(0)
    sign = math.copysign(1.0, b_p_mm)
    assert camera_omega_b(_result(sign * 120.0, b_p_mm=b_p_mm, trace=False), rng) == (120.0, 1.5)
    assert camera_omega_b(_result(sign * 120.0, b_p_mm=b_p_mm, periods=0), rng) == (120.0, 1.5)
    # 2 periods at 20 Hz = 0.1 s: 3 frames at 30 fps are fitted, at 10 fps (2 frames) the probe's own value
    short = _result(sign * 120.0, b_p_mm=b_p_mm, measure_s=0.05)
    assert camera_omega_b(short, rng, fps=10.0) == (120.0, 1.5)
    assert camera_omega_b(short, rng, fps=30.0, angle_noise_deg=0.0)[0] == pytest.approx(120.0, rel=1e-9)


def test_noise_gives_an_unbiased_slope_whose_spread_the_standard_error_states():
    """White angle noise s on N frames over T: the slope's standard deviation is s / sqrt(sum (t - t_mean)^2)."""
    rng = np.random.default_rng(7)
    res = _result(-300.0, b_p_mm=-3.0)
    noise = 0.5
    draws = np.array([camera_omega_b(res, rng, fps=30.0, angle_noise_deg=noise) for _ in range(2000)])
    frames = np.arange(0.0, res.periods_measured / 20.0 + 1e-12, 1 / 30.0)
    sd_theory = noise / math.sqrt(np.sum((frames - frames.mean()) ** 2))
    assert np.mean(draws[:, 0]) == pytest.approx(300.0, abs=4 * sd_theory / math.sqrt(2000))
    assert np.std(draws[:, 0]) == pytest.approx(sd_theory, rel=0.05)
    assert np.mean(draws[:, 1]) == pytest.approx(sd_theory, rel=0.05)
    assert np.all(draws[:, 1] >= sd_theory * (1 - 1e-12))  # never below what the noise alone implies
    assert np.mean(np.abs(draws[:, 0] - 300.0) <= draws[:, 1]) == pytest.approx(0.68, abs=0.04)


def test_a_wobbling_disc_gets_the_error_of_its_residuals():
    """Residuals larger than the angle noise (a disc that wobbles) set the standard error, not the noise."""
    spec = ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(20.0, 3.0, 3.0))
    t = np.arange(0.0, spec.duration_s + 5e-4, 1e-3)
    wobble = np.radians(3.0) * np.sin(2 * math.pi * 7.3 * t)
    res = ProbeResult(spec=spec, omega_b_deg_s=100.0, stderr_deg_s=1.0, unstable=False, reason=None,
                      sim_s=spec.duration_s, wall_s=0.0, periods_measured=spec.n_periods,
                      trace=YawTrace(t=t, yaw=np.radians(100.0) * t + wobble, centre_u=0 * t, centre_v=0 * t))
    omega, se = camera_omega_b(res, np.random.default_rng(0), angle_noise_deg=0.0)
    frames = spec.measure_start_s + np.arange(0.0, spec.n_periods / 20.0 + 1e-12, 1 / 30.0)
    y = np.degrees(np.interp(frames, t, res.trace.yaw))
    slope, icpt = np.polyfit(frames, y, 1)
    resid = y - (slope * frames + icpt)
    expected_se = math.sqrt(resid @ resid / (frames.size - 2) / np.sum((frames - frames.mean()) ** 2))
    assert omega == pytest.approx(slope, rel=1e-9) and se == pytest.approx(expected_se, rel=1e-6)
    assert se > 1.0


def test_edges_one_period_two_samples_three_frames_and_a_still_plate():
    """The camera fits whenever it has >= 1 period, >= 2 trace samples and >= 3 frames (else the probe's value)."""
    rng = np.random.default_rng(0)
    one = _result(250.0, periods=1)
    one = ProbeResult(**{**one.__dict__, "omega_b_deg_s": 120.0})  # the probe's own value differs from the trace
    assert camera_omega_b(one, rng, fps=100.0, angle_noise_deg=0.0)[0] == pytest.approx(250.0, rel=1e-9)
    spec = one.spec
    t = np.array([0.0, spec.duration_s])
    two = ProbeResult(**{**one.__dict__, "periods_measured": spec.n_periods,
                         "trace": YawTrace(t=t, yaw=math.radians(250.0) * t, centre_u=0 * t, centre_v=0 * t)})
    assert camera_omega_b(two, rng, angle_noise_deg=0.0)[0] == pytest.approx(250.0, rel=1e-9)
    three = ProbeResult(**{**_result(250.0, measure_s=0.05).__dict__, "omega_b_deg_s": 120.0})  # 2 periods = 0.1 s
    assert camera_omega_b(three, rng, fps=20.0, angle_noise_deg=0.0)[0] == pytest.approx(250.0, rel=1e-9)
    still = _result(0.0, a_p_deg=3.0, b_p_mm=0.0)
    assert camera_omega_b(still, rng, angle_noise_deg=0.0) == pytest.approx((0.0, 0.0), abs=1e-9)
