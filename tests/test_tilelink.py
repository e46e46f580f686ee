"""The paper's tile-link model (point-mass reduction): geometry, modal omega_n, behaviour, and extreme settings
(a seconds-long version of experiments/stress.py): unstable with a reason and finite numbers, never NaN."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.core.probe import REASONS, ProbeResult
from plate_env.physics.tilelink.geometry import disc_geometry
from plate_env.physics.tilelink.pointmass import build_params, modal


def probe(obj, f_p_hz, a_p_deg=3.0, b_p_mm=3.0, **kw):
    return pe.ProbeSpec(obj, pe.PlateMotion.from_paper(f_p_hz, a_p_deg, b_p_mm), **kw)


def test_geometry_52_tiles_88_joints():
    g = disc_geometry(0.08)
    assert g.n_nodes == 52
    assert len(g.links) == 88
    assert sorted(np.bincount(np.round(g.rest[:, 1] * 1000).astype(int) + 35)[::10].tolist()) == sorted(
        [4, 6, 8, 8, 8, 8, 6, 4])
    assert np.all(np.hypot(g.rest[:, 0], g.rest[:, 1]) <= 0.04 + 1e-12)


@pytest.mark.parametrize("omega_n_pi", [1.4, 3.5, 10.0, 23.0, 33.0, 40.0, 50.0])
def test_modal_omega_n_hit_within_half_percent(omega_n_pi):
    obj = pe.ObjectSpec.from_paper(omega_n_pi, 36.9)
    params = build_params(obj)
    result = modal(obj, params.k_bending)
    assert result.n_zero == 7  # 6 rigid motions + the free twist
    assert result.omega_bending == pytest.approx(obj.omega_n, rel=5e-3)


@pytest.mark.parametrize("dt", [2e-4, 4e-4])
def test_still_plate_leaves_disc_still(dt, cheese):
    """A plate that does not move leaves the disc where it is, at the default step and at twice it (2.7 s)."""
    physics = pe.make_physics("tilelink", dt=dt)
    spec = pe.ProbeSpec(cheese, pe.PlateMotion(freq_hz=20.0, amp_rad=0.0, b_p=0.0), settle_s=0.5, measure_s=2.0,
                        record_trace=True)
    r = physics.run([spec])[0]
    assert not r.unstable and _finite(r)
    tr = r.trace
    assert tr is not None and np.all(np.isfinite(tr.yaw)) and np.all(np.isfinite(tr.centre_u))
    assert abs(r.omega_b_deg_s) < 0.01
    assert np.max(np.abs(tr.centre_u)) < 1e-6 and np.max(np.abs(tr.centre_v)) < 1e-6
    drift = math.hypot(tr.centre_u[-1] - tr.centre_u[0], tr.centre_v[-1] - tr.centre_v[0])
    assert drift < 1e-4  # m over 2.7 s


def test_rotation_sign_flips_with_bp(tilelink, cheese):
    pos, neg = tilelink.run([probe(cheese, 24.0, b_p_mm=3.0), probe(cheese, 24.0, b_p_mm=-3.0)])
    assert not pos.unstable and not neg.unstable
    assert pos.omega_b_deg_s > 100  # counter-clockwise for A_p * B_p > 0 in our convention
    assert neg.omega_b_deg_s < -100
    assert pos.omega_b_deg_s == pytest.approx(-neg.omega_b_deg_s, rel=0.05)


def test_resonance_like_rise(tilelink, cheese):
    low, peak = tilelink.run([probe(cheese, 12.0), probe(cheese, 25.0)])
    assert not peak.unstable
    assert peak.omega_b_deg_s > 3 * low.omega_b_deg_s > 0


def test_batch_equals_single_runs(tilelink):
    probes = [probe(pe.ObjectSpec.from_paper(w, a), f) for w, a, f in
              ((3.5, 36.9, 20.0), (10.0, 45.0, 25.0), (33.0, 56.3, 27.0), (23.0, 36.9, 36.0))]
    batch = tilelink.run(probes)
    singles = [tilelink.run([p])[0] for p in probes]
    for b, s in zip(batch, singles, strict=True):
        assert (b.omega_b_deg_s, b.stderr_deg_s, b.unstable, b.reason, b.sim_s) == (
            s.omega_b_deg_s, s.stderr_deg_s, s.unstable, s.reason, s.sim_s)


def test_huge_dt_is_reported_unstable_with_a_reason_not_nan(cheese):
    with pytest.warns(UserWarning, match="dt = 0.005 s is above the largest time step measured stable"):
        physics = pe.make_physics("tilelink", dt=5e-3)
    specs = [probe(cheese, 25.0)] + [probe(pe.ObjectSpec.from_paper(w, 36.9), 25.0, settle_s=0.2, measure_s=0.3)
                                     for w in (1.4, 10.0, 40.0)]
    res = physics.run(specs)
    assert all(r.unstable and r.reason in ("non_finite", "runaway_energy", "left_plate", "overturned") for r in res)
    assert all(_finite(r) for r in res)


def test_injected_nan_is_reported_non_finite(tilelink, cheese):
    from plate_env.core.probe import Status
    from plate_env.physics.tilelink.backend import _ainv, _pointmass_params, result_from_arrays
    from plate_env.physics.tilelink.params import P_KB

    spec = probe(cheese, 25.0)
    prm = tilelink._param_vector(spec)[None, :]
    prm[0, P_KB] = float("nan")
    params = _pointmass_params(cheese, tilelink.config)
    raw = tilelink.run_param_arrays(prm, _ainv(cheese, tilelink.config, tilelink.dt)[None], params.geom.rest[None],
                                    params.geom)
    assert raw["status"][0] == Status.NON_FINITE
    result = result_from_arrays(spec, raw, 0, tilelink.dt)
    assert result.unstable and result.reason == "non_finite"
    assert result.omega_b_deg_s == 0.0


def test_bad_time_step_rejected():
    with pytest.raises(ValueError, match="time step"):
        pe.make_physics("tilelink", dt=float("nan"))
    with pytest.raises(ValueError, match="unknown tilelink model"):
        pe.make_physics("tilelink", model="fem")


def test_first_hump_peak_in_band_and_not_falling_with_omega_n(tilelink):
    from plate_env.identify.fitting import first_hump_mask

    freqs = np.arange(14.0, 35.0, 1.0)
    peaks = []
    for w in (3.5, 10.0, 23.0, 33.0):
        obj = pe.ObjectSpec.from_paper(w, 36.9)
        res = tilelink.run([probe(obj, f) for f in freqs])
        om = np.array([r.omega_b_deg_s for r in res])
        mask = first_hump_mask(freqs, om, np.array([not r.unstable for r in res]))
        k = int(np.argmax(np.where(mask, om, -np.inf)))
        assert om[k] > 3 * om[0]  # resonance-like rise from 14 Hz
        peaks.append(freqs[k])
    assert all(20.0 <= p <= 32.0 for p in peaks), peaks
    assert all(b >= a for a, b in zip(peaks, peaks[1:], strict=False)), peaks


def test_rigid_model_is_a_different_model_behind_the_same_interface(cheese):
    spec = probe(cheese, 22.0)
    pm = pe.make_physics("tilelink", model="pointmass").run([spec])[0]
    rg = pe.make_physics("tilelink", model="rigid").run([spec])[0]
    assert not rg.unstable and rg.omega_b_deg_s > 100
    assert rg.omega_b_deg_s != pm.omega_b_deg_s


def _finite(r: ProbeResult) -> bool:
    nums = (r.omega_b_deg_s, r.stderr_deg_s, r.sim_s, r.wall_s)
    return all(math.isfinite(x) for x in nums) and r.periods_measured >= 0


def test_extreme_amplitudes_and_frequencies_are_finite(tilelink):
    specs = [probe(pe.ObjectSpec.from_paper(w, al), f, a, settle_s=0.2, measure_s=0.3) for w in (1.4, 40.0)
             for a in (1.0, 24.0, 45.0) for f in (5.0, 45.0) for al in (20.0, 70.0)]
    res = tilelink.run(specs)
    assert all(_finite(r) for r in res)
    assert all((r.reason in REASONS) if r.unstable else r.reason is None for r in res)
    # a 45 deg plate shaken at 45 Hz throws the disc off
    wild = [r for r in res if r.spec.motion.a_p_deg > 40 and r.spec.motion.freq_hz > 40]
    assert all(r.unstable for r in wild)
