"""Plate motion, Eqs. (1)-(2) of the paper, with a smooth start-up ramp.

Conventions (used by every physics backend):

* World frame: ``x`` is the horizontal axis the plate translates along and rotates about, ``z`` points up,
  ``y = z x x``. The rotation axis lies in the plate's top surface and passes through the plate centre.
* ``Theta(t) = -A_p sin(2 pi f_p t)`` is a right-handed rotation about ``+x``; ``X(t) = B_p sin(2 pi f_p t)``
  translates the plate along ``+x``. Both are multiplied by the ramp ``r(t) = (1 - cos(pi t / T_r)) / 2`` for
  ``t < T_r`` (1 afterwards), so the plate starts from rest with zero velocity.
* The plate frame has its origin at the plate centre ``(X, 0, 0)``, its ``u`` axis along ``x`` and its normal
  ``n = (0, -sin Theta, cos Theta)``. The disc's yaw is measured about ``n``; a positive angular velocity
  ``omega_B`` is counter-clockwise seen from above. Its sign follows the sign of ``A_p * B_p``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from plate_env.core.setup import AMP_RANGE_RAD, B_P_RANGE_M, FREQ_RANGE_HZ, PAPER_SETUP


def plate_state(
    t: float, freq_hz: float, amp_rad: float, b_p: float, ramp_s: float
) -> tuple[float, float, float, float]:
    """Plate kinematics at time ``t`` (s): ``(Theta [rad], dTheta/dt [rad/s], X [m], dX/dt [m/s])``.

    Plain scalar arithmetic so that numba can compile this very function for the physics kernels.
    """
    w = 2.0 * math.pi * freq_hz
    s = math.sin(w * t)
    c = math.cos(w * t)
    if ramp_s > 0.0 and t < ramp_s:
        r = 0.5 * (1.0 - math.cos(math.pi * t / ramp_s))
        dr = 0.5 * math.pi / ramp_s * math.sin(math.pi * t / ramp_s)
    else:
        r = 1.0
        dr = 0.0
    theta = -amp_rad * r * s
    theta_dot = -amp_rad * (dr * s + r * w * c)
    x = b_p * r * s
    x_dot = b_p * (dr * s + r * w * c)
    return theta, theta_dot, x, x_dot


@dataclass(frozen=True)
class PlateMotion:
    """A sinusoidal plate motion (SI units).

    Attributes:
        freq_hz: plate frequency f_p, Hz.
        amp_rad: angular amplitude A_p, rad.
        b_p: linear amplitude B_p, m.
        ramp_s: duration of the smooth start-up ramp, s.
    """

    freq_hz: float
    amp_rad: float
    b_p: float = PAPER_SETUP.b_p
    ramp_s: float = 0.2

    def __post_init__(self) -> None:
        for label, value, (lo, hi) in (
            ("f_p (Hz)", self.freq_hz, FREQ_RANGE_HZ),
            ("A_p (rad)", self.amp_rad, AMP_RANGE_RAD),
            ("B_p (m)", self.b_p, B_P_RANGE_M),
            ("ramp (s)", self.ramp_s, (0.0, 60.0)),
        ):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"PlateMotion {label} = {value!r} is outside the allowed range [{lo}, {hi}]")

    @classmethod
    def from_paper(cls, f_p_hz: float, a_p_deg: float, b_p_mm: float = PAPER_SETUP.b_p_mm,
                   ramp_s: float = 0.2) -> PlateMotion:
        """Build from the paper's units: Hz, degrees, millimetres."""
        return cls(freq_hz=f_p_hz, amp_rad=math.radians(a_p_deg), b_p=b_p_mm * 1e-3, ramp_s=ramp_s)

    @property
    def a_p_deg(self) -> float:
        return math.degrees(self.amp_rad)

    def state(self, t: float) -> tuple[float, float, float, float]:
        """``(Theta, dTheta/dt, X, dX/dt)`` at time ``t`` (s)."""
        return plate_state(t, self.freq_hz, self.amp_rad, self.b_p, self.ramp_s)

    def peak_speed(self, radius: float) -> float:
        """Largest speed of a plate point within ``radius`` (m) of the centre, m/s."""
        return 2 * math.pi * self.freq_hz * (abs(self.b_p) + abs(self.amp_rad) * radius)
