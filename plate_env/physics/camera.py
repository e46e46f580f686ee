"""What a camera sees: the disc's yaw sampled at a frame rate with angle noise, and omega_B fitted from it."""

from __future__ import annotations

import math

import numpy as np

from plate_env.core.probe import ProbeResult


def camera_omega_b(result: ProbeResult, rng: np.random.Generator, fps: float = 30.0,
                   angle_noise_deg: float = 0.5) -> tuple[float, float]:
    """omega_B (deg/s, sign-normalised by sign(A_p * B_p)) and its standard error from camera frames.

    Frames are taken at ``fps`` over the probe's measurement window (up to the failure of an unstable probe),
    the yaw of each frame is the simulated yaw plus Gaussian noise of ``angle_noise_deg``, and omega_B is the
    least-squares slope of yaw against time (its standard error from the residuals, never below the slope error
    the noise alone implies). With fewer than 3 frames the probe's own value is returned.
    """
    spec = result.spec
    sign = 1.0 if spec.motion.amp_rad * spec.motion.b_p >= 0 else -1.0
    tr = result.trace
    if tr is None or result.periods_measured < 1 or len(tr.t) < 2:
        return sign * result.omega_b_deg_s, result.stderr_deg_s
    t0 = spec.measure_start_s
    t1 = t0 + result.periods_measured / spec.motion.freq_hz
    frames = t0 + np.arange(0.0, t1 - t0 + 1e-12, 1.0 / fps)
    if frames.size < 3:
        return sign * result.omega_b_deg_s, result.stderr_deg_s
    yaw = np.degrees(np.interp(frames, tr.t, tr.yaw)) + rng.normal(0.0, angle_noise_deg, frames.size)
    tc = frames - frames.mean()
    sxx = float(tc @ tc)
    centred = yaw - yaw.mean()
    slope = float(tc @ centred / sxx)
    resid = centred - slope * tc
    se = math.sqrt(max(float(resid @ resid) / (frames.size - 2), angle_noise_deg ** 2) / sxx)
    return sign * slope, se
