"""A seconds-long version of experiments/stress.py: extreme settings give unstable results with a reason and
finite numbers, never NaN, and a still plate keeps the disc still."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.physics.base import REASONS, ProbeResult


def _finite(r: ProbeResult) -> bool:
    nums = (r.omega_b_deg_s, r.stderr_deg_s, r.sim_s, r.wall_s)
    return all(math.isfinite(x) for x in nums) and r.periods_measured >= 0


def _probe(omega_pi: float, a_p_deg: float, f_hz: float, alpha_deg: float = 36.9, **kw) -> pe.ProbeSpec:
    return pe.ProbeSpec(pe.ObjectSpec.from_paper(omega_pi, alpha_deg), pe.PlateMotion.from_paper(f_hz, a_p_deg),
                        settle_s=0.2, measure_s=0.3, **kw)


def test_huge_time_step_is_unstable_with_reason():
    with pytest.warns(UserWarning, match="dt = 0.005 s is above the largest time step measured stable"):
        physics = pe.make_physics("tilelink", dt=5e-3)
    res = physics.run([_probe(w, 3.0, 25.0) for w in (1.4, 10.0, 40.0)])
    assert all(r.unstable and r.reason in REASONS for r in res), [(r.unstable, r.reason) for r in res]
    assert all(_finite(r) for r in res)


def test_extreme_amplitudes_and_frequencies_are_finite(tilelink):
    specs = [_probe(w, a, f, al) for w in (1.4, 40.0) for a in (1.0, 24.0, 45.0) for f in (5.0, 45.0)
             for al in (20.0, 70.0)]
    res = tilelink.run(specs)
    assert all(_finite(r) for r in res)
    assert all((r.reason in REASONS) if r.unstable else r.reason is None for r in res)
    # a 45 deg plate shaken at 45 Hz throws the disc off
    wild = [r for r in res if r.spec.motion.a_p_deg > 40 and r.spec.motion.freq_hz > 40]
    assert all(r.unstable for r in wild)


@pytest.mark.parametrize("dt", [2e-4, 4e-4])
def test_still_plate_keeps_disc_still(dt):
    physics = pe.make_physics("tilelink", dt=dt)
    spec = pe.ProbeSpec(pe.ObjectSpec.from_paper(10.0, 36.9), pe.PlateMotion(freq_hz=20.0, amp_rad=0.0, b_p=0.0),
                        settle_s=0.5, measure_s=2.0, record_trace=True)
    r = physics.run([spec])[0]
    assert not r.unstable and _finite(r)
    tr = r.trace
    assert tr is not None and np.all(np.isfinite(tr.yaw)) and np.all(np.isfinite(tr.centre_u))
    assert abs(r.omega_b_deg_s) < 0.5
    drift = math.hypot(tr.centre_u[-1] - tr.centre_u[0], tr.centre_v[-1] - tr.centre_v[0])
    assert drift < 1e-4  # m over 2.7 s
