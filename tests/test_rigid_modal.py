"""The experimental modal (floating-frame) rigid-tile disc (issue 34): its reduction is the rigid-tile disc's."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import plate_env as pe
from plate_env.physics.tilelink.rigid import RIGID_LIMIT_CONFIG, _row_values, bending_stiffness, mass_matrix
from plate_env.physics.tilelink.rigid_modal import (
    ModalDiscConfig,
    _rigid_modes,
    build_modal_params,
    joint_rows,
)

OBJ = pe.ObjectSpec.from_paper(10.0, 36.9)


def test_modes_are_mass_normalised_mean_axes_and_below_the_cutoff():
    p = build_modal_params(OBJ)
    mm = mass_matrix(p.geom, p.tile_mass)
    np.testing.assert_allclose(p.phi.T @ mm @ p.phi, np.eye(p.phi.shape[1]), atol=1e-8)
    # mean axes: no flexible mode moves the mass centre or carries angular momentum at rest
    rig = _rigid_modes(p.geom)
    assert np.abs(rig.T @ mm @ p.phi).max() < 1e-8
    assert p.omega.max() < 2 * math.pi * 200.0
    # the same bending stiffness as the rigid limit, hitting omega_n (the lowest non-twist mode)
    assert p.k_bending == pytest.approx(bending_stiffness(OBJ, RIGID_LIMIT_CONFIG), rel=1e-12)
    assert p.omega[1] == pytest.approx(OBJ.omega_n, rel=1e-3)


@pytest.mark.slow
def test_cutoff_keeps_fewer_modes():
    assert build_modal_params(OBJ, ModalDiscConfig(cutoff_hz=100.0)).phi.shape[1] < build_modal_params(OBJ).phi.shape[1]


@pytest.mark.parametrize("bend_deg", [3.0, 9.0])
def test_condensed_stiffening_matches_the_exact_joint_rows(bend_deg):
    """E2 + E3 + E4 of the reduction against the joints' exact energy at the displacement phi q + U s (the first
    bending mode bent so that its largest tile rotation is ``bend_deg``); the linear energy alone is far off."""
    p = build_modal_params(OBJ)
    row_k, _ = _row_values(p.geom, p.tile_mass, p.k_bending, OBJ.omega_n, RIGID_LIMIT_CONFIG)
    w = np.tile(row_k, len(p.geom.links))
    rot = np.zeros(p.phi.shape[0], dtype=bool)
    rot[3::6] = True
    rot[4::6] = True
    q = np.zeros(p.phi.shape[1])
    q[1] = math.radians(bend_deg) / np.abs(p.phi[rot, 1]).max()
    s = np.array([q[a] * q[b] for a, b in p.pairs])
    e2 = 0.5 * float((p.omega**2 * q**2).sum())
    model = e2 + float(q @ p.b_cubic @ s) + 0.5 * float(s @ p.h_quartic @ s)
    exact = 0.5 * float((w * joint_rows(p.geom, p.phi @ q + p.u_static @ s).ravel() ** 2).sum())
    assert model == pytest.approx(exact, rel=0.08)
    assert e2 < 0.5 * exact


def test_config_refuses_bad_values():
    with pytest.raises(ValueError, match="n_nonlinear"):
        ModalDiscConfig(n_nonlinear=81)
    with pytest.raises(ValueError, match="cutoff_hz"):
        ModalDiscConfig(cutoff_hz=0.0)
    with pytest.raises(ValueError, match="n_nonlinear"):
        ModalDiscConfig(n_nonlinear=-1)


@pytest.mark.slow
def test_one_reference_probe():
    """10pi, 24 Hz, 3 deg (the reference's first hump): within 3 % of the converged rigid limit."""
    from plate_env.core.probe import ProbeSpec
    from plate_env.physics.tilelink.rigid_modal_kernels import RigidModalPhysics

    ref = json.loads((Path(__file__).parents[1] / "experiments/results/rigid_reference.json").read_text())
    row = next(r for r in ref["probes"] if r["key"] == "10pi_36.9deg_24Hz")
    spec = ProbeSpec(obj=pe.ObjectSpec.from_paper(row["omega_n_pi"], row["alpha_deg"]),
                     motion=pe.PlateMotion.from_paper(row["f_p_hz"], row["a_p_deg"], row["b_p_mm"]),
                     settle_s=row["settle_s"], measure_s=row["measure_s"], initial_yaw=row["initial_yaw_rad"],
                     initial_offset=tuple(row["initial_offset_m"]))
    res = RigidModalPhysics(2e-4).run([spec])[0]
    assert not res.unstable
    assert res.omega_b_deg_s == pytest.approx(row["omega_b_deg_s"], rel=0.03)


@pytest.mark.slow
@pytest.mark.parametrize("mode", [1, 12, 17])
def test_condensed_stiffening_matches_the_exact_static_minimum(mode):
    """With all of the 30 lowest out-of-plane modes nonlinear, E2 + E3 + E4 of a mode bent to a 9 deg largest tile
    rotation is within 3 % of the exact joint rows' energy minimised over the static (above cut-off) modes
    (least squares); the default 10 nonlinear modes leave mode 12 (23.7 Hz at 10pi, near the first hump) linear,
    about 30x too soft there (experiments/results/rigid_modal_notes.md)."""
    import scipy.linalg
    import scipy.optimize

    from plate_env.physics.tilelink.rigid import linear_stiffness

    p = build_modal_params(OBJ, ModalDiscConfig(n_nonlinear=30))
    row_k, _ = _row_values(p.geom, p.tile_mass, p.k_bending, OBJ.omega_n, RIGID_LIMIT_CONFIG)
    sw = np.sqrt(np.tile(row_k, len(p.geom.links)))
    ev, evec = scipy.linalg.eigh(linear_stiffness(p.geom, row_k), mass_matrix(p.geom, p.tile_mass))
    phis = evec[:, np.sqrt(np.clip(ev, 0.0, None)) >= 2 * math.pi * 200.0]
    rot = np.zeros(p.phi.shape[0], dtype=bool)
    rot[3::6] = True
    rot[4::6] = True
    q = np.zeros(p.phi.shape[1])
    q[mode] = math.radians(9.0) / np.abs(p.phi[rot, mode]).max()
    e2 = 0.5 * float((p.omega**2 * q**2).sum())

    def model(pp):
        s = np.array([q[a] * q[b] for a, b in pp.pairs])
        return e2 + float(q @ pp.b_cubic @ s) + 0.5 * float(s @ pp.h_quartic @ s)

    fit = scipy.optimize.least_squares(lambda y: sw * joint_rows(p.geom, p.phi @ q + phis @ y).ravel(),
                                       np.zeros(phis.shape[1]), method="lm", x_scale=1e-4)
    exact = 0.5 * float((fit.fun**2).sum())
    assert model(p) == pytest.approx(exact, rel=0.03)
    assert exact > 2.5 * e2
    if mode >= 10:
        assert model(build_modal_params(OBJ)) == pytest.approx(e2, rel=1e-9)


@pytest.mark.parametrize(("omega", "damp"), [(2 * math.pi * 25.0, 3.0), (2 * math.pi * 800.0, 400.0),
                                             (2 * math.pi * 1500.0, 30000.0), (0.0, 0.0)])
def test_exact_propagator_reproduces_a_free_damped_oscillator(omega, damp):
    """The exact modal propagator (issue 34, h34e) steps a free damped oscillator ``q'' + c q' + w^2 q = 0`` (and
    one under a constant force) onto its closed-form solution to machine precision at any step; backward Euler at
    the same step (w dt = 1.5 for the 800 Hz mode: the kernel's dt 4e-4 at ~600 Hz) is far off."""
    from plate_env.physics.tilelink.rigid_modal import modal_propagator

    dt = 1.5 / omega if omega else 4e-4
    n_steps, q0, v0, f = 40, 1e-3, -0.2, 7.0

    def closed_form(t):
        """q(t), v(t) with the constant force f (the particular solution f / w^2, or f t^2 / 2 at w = 0)."""
        if omega == 0.0:
            return q0 + v0 * t + 0.5 * f * t * t, v0 + f * t
        qs = f / omega**2
        lam = np.roots([1.0, damp, omega**2]).astype(complex)
        a = np.linalg.solve(np.array([[1.0, 1.0], lam]), np.array([q0 - qs, v0], dtype=complex))
        return float((a * np.exp(lam * t)).sum().real + qs), float((a * lam * np.exp(lam * t)).sum().real)

    for method, tol_ok in (("exact", True), ("backward_euler", False)):
        pr = modal_propagator(np.array([omega]), np.array([damp]), dt, method)[0]
        q, v = q0, v0
        errs = []
        for k in range(1, n_steps + 1):
            q, v = pr[0] * q + pr[1] * v + pr[4] * f, pr[2] * q + pr[3] * v + pr[5] * f
            qe, ve = closed_form(k * dt)
            errs.append(abs(q - qe) / abs(q0))
        if tol_ok:
            assert max(errs) < 1e-12, (method, max(errs))
        elif omega > 0.0:
            assert max(errs) > 1e-2, (method, max(errs))


def test_exact_propagator_refuses_bad_values():
    from plate_env.physics.tilelink.rigid_modal import modal_propagator

    with pytest.raises(ValueError, match="dt"):
        modal_propagator(np.array([1.0]), np.array([0.0]), 0.0)
    with pytest.raises(ValueError, match="method"):
        modal_propagator(np.array([1.0]), np.array([0.0]), 1e-4, "rk4")
