"""The rigid-tile tile-link model: modal target, rest, rotation sign, dt convergence, batching, failure checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.core.probe import ProbeSpec, Status
from plate_env.physics.tilelink import rigid
from plate_env.physics.tilelink import rigid_kernels as rk
from plate_env.physics.tilelink.backend import result_from_arrays
from plate_env.physics.tilelink.params import DEFAULT_DT, P_NSTEPS, P_RECEVERY

DT = DEFAULT_DT["rigid"]


def _probe(f_hz: float, a_deg: float = 3.0, b_mm: float = 3.0, omega_pi: float = 10.0, alpha: float = 36.9,
           settle: float = 0.4, measure: float = 0.4) -> ProbeSpec:
    obj = pe.ObjectSpec.from_paper(omega_pi, alpha)
    return ProbeSpec(obj=obj, motion=pe.PlateMotion.from_paper(f_hz, a_deg, b_mm), settle_s=settle,
                     measure_s=measure)


def _omega(out: dict, b: int, spec: ProbeSpec, dt: float) -> tuple[float, Status]:
    """omega_B (deg/s) and status of probe ``b`` from the raw arrays (the backend's own conversion)."""
    r = result_from_arrays(spec, out, b, dt)
    return r.omega_b_deg_s, Status(int(out["status"][b]))


@pytest.mark.parametrize("omega_pi", [1.4, 10.0, 33.0, 50.0])
def test_modal_hits_omega_n(omega_pi):
    obj = pe.ObjectSpec.from_paper(omega_pi, 36.9)
    p = rigid.build_params(obj)
    assert p.modal.omega_bending == pytest.approx(obj.omega_n, rel=5e-3)
    assert p.modal.n_zero == 7  # 6 rigid motions + the free twist


def test_still_plate_leaves_disc_still():
    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    spec = ProbeSpec(obj=obj, motion=pe.PlateMotion(freq_hz=20.0, amp_rad=0.0, b_p=0.0), settle_s=0.3,
                     measure_s=0.3)
    out = rk.run_rigid_arrays([spec])
    w, st = _omega(out, 0, spec, DT)
    n = int(out["nrec"][0])
    assert st == Status.OK
    assert abs(w) < 0.5
    assert math.hypot(out["cu"][0, n - 1], out["cv"][0, n - 1]) < 5e-4


def test_rotation_sign_flips_with_b_p():
    specs = [_probe(22.0, b_mm=3.0), _probe(22.0, b_mm=-3.0)]
    out = rk.run_rigid_arrays(specs)
    (w_pos, s_pos), (w_neg, s_neg) = (_omega(out, b, s, DT) for b, s in enumerate(specs))
    assert s_pos == Status.OK and s_neg == Status.OK
    assert w_pos > 50.0 and w_neg < -50.0  # A_p B_p > 0 turns clockwise in the paper, sign convention of motion.py


def test_batch_equals_single():
    specs = [_probe(20.0, settle=0.1, measure=0.1), _probe(24.0, omega_pi=33.0, settle=0.1, measure=0.1)]
    batch = rk.run_rigid_arrays(specs)
    for b, s in enumerate(specs):
        single = rk.run_rigid_arrays([s])
        n = int(single["nrec"][0])
        assert int(batch["nrec"][b]) == n
        assert int(batch["status"][b]) == int(single["status"][0])
        np.testing.assert_array_equal(batch["yaw"][b, :n], single["yaw"][0, :n])


def test_energy_from_nowhere_is_runaway():
    spec = _probe(20.0, settle=0.2, measure=0.1)
    prm = rk.param_vector(spec, DT, 0.010)
    prm[rk.R_CB] = -20.0 * prm[rk.R_CB] - 1e-6  # a negative bending damper pumps energy in
    geom = rigid.disc_geometry(spec.obj.diameter)
    out = rk.run_rigid_param_arrays(prm[None, :], geom.rest[None], geom)
    assert int(out["status"][0]) in (Status.RUNAWAY, Status.FOLDED, Status.NON_FINITE)


def test_returns_backend_keys():
    out = rk.run_rigid_arrays([_probe(20.0, settle=0.05, measure=0.1)])
    for key in ("prm", "yaw", "cu", "cv", "status", "nrec"):
        assert key in out
    assert out["prm"][0, P_NSTEPS] > 0 and out["prm"][0, P_RECEVERY] >= 1


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="target missed, measured (experiments/results/bench_models.md): dt 2e-4 vs "
                   "dt/4 differs by -0.1/+0.3/-3.5 % at 18/22/25 Hz; 1 % at all three needs dt ~2.5e-5 (~8x slower). "
                   "A first-order error of the step across the band (up to -6.6 % against dt 1.25e-5), insensitive "
                   "to contact, friction, row damping and sweeps (experiments/results/dt_error_sources.md).")
def test_dt_convergence_three_frequencies():
    specs = [_probe(f, settle=0.6, measure=1.0) for f in (18.0, 22.0, 25.0)]
    coarse = rk.run_rigid_arrays(specs, dt=DT)
    fine = rk.run_rigid_arrays(specs, dt=DT / 4,
                               config=rigid.RigidTileConfig(iterations=2 * rigid.RigidTileConfig().iterations))
    for b, s in enumerate(specs):
        wc, sc = _omega(coarse, b, s, DT)
        wf, sf = _omega(fine, b, s, DT / 4)
        assert sc == Status.OK and sf == Status.OK
        assert wc == pytest.approx(wf, rel=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("model", ["rigid", "rigid_limit"])
def test_first_hump_rises_with_omega_n(model):
    """The protocol of experiments/bench_models.py (14-34 Hz step 1, default windows, the package's first-hump
    fit), so this test and the reported table measure the same thing."""
    from plate_env.identify.fitting import fit_lorentzian

    freqs = np.arange(14.0, 35.0, 1.0)
    physics = pe.make_physics("tilelink", model=model)
    f0 = {}
    for wn in (10.0, 33.0):
        obj = pe.ObjectSpec.from_paper(wn, 36.9)
        res = physics.run([ProbeSpec(obj=obj, motion=pe.PlateMotion.from_paper(float(f), 3.0, 3.0)) for f in freqs])
        fit = fit_lorentzian(freqs, [r.omega_b_deg_s for r in res], unstable=[r.unstable for r in res])
        assert fit.ok, fit.reason
        f0[wn] = fit.f0
    assert f0[33.0] - f0[10.0] >= 2.0


@pytest.mark.slow
def test_large_fold_is_detected_not_launched():
    specs = [_probe(f, a_deg=12.0, omega_pi=wn, settle=0.8, measure=1.0) for wn in (3.0, 5.0) for f in (12.0, 16.0)]
    out = rk.run_rigid_arrays(specs)
    for b in range(len(specs)):
        assert int(out["status"][b]) not in (Status.NON_FINITE, Status.RUNAWAY)
        assert out["diag"][b, 0] <= 0.1 * out["diag"][b, 2] + 2e-4


def test_rigid_limit_is_the_rigid_kernel_with_stiff_rows_and_a_small_step():
    physics = pe.make_physics("tilelink", model="rigid_limit")
    assert physics.dt == pytest.approx(2.5e-5)
    assert physics.rigid_config == rigid.RIGID_LIMIT_CONFIG
    assert physics.rigid_config.omega_rigid > 5 * rigid.RigidTileConfig().omega_rigid
    res = physics.run([_probe(22.0, settle=0.02, measure=0.05)])[0]
    assert not res.unstable and math.isfinite(res.omega_b_deg_s)
    with pytest.raises(ValueError, match="rigid_limit"):
        pe.make_physics("tilelink", model="rigid-limit")
