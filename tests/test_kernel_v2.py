"""The point-mass kernel v2 (``TileLinkPhysics(kernel="v2")``, ``plate_env/physics/tilelink/kernels_v2.py``): its
grid layout and damper blocks against the geometry and the dense damper, omega_B against v1 within each probe's
standard error, batch against single runs, and blow-ups reported with a reason. The same-numbers guarantee across
processes and the disk cache is tested in ``tests/test_determinism.py``."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.physics.tilelink.geometry import disc_geometry
from plate_env.physics.tilelink.pointmass import (
    PARITY_SIGNS,
    build_params,
    grid_damping_blocks,
    grid_layout,
    implicit_damping_matrix,
)
from plate_env.run.sweeps import backend_tag

#: omega_B (deg/s) and its standard error from v1 (the code of main at 284a76f, unchanged) for the probes of
#: ``reference_probes``, recorded on the project machine by experiments/bench_kernel.py
#: (experiments/results/bench_kernel.json): v1 must keep them, v2 must hit them within the stderr.
V1_REFERENCE = ((67.65200522194137, 0.6322736001825218), (401.0292861052719, 4.79346265972213),
                (620.5497892388142, 1.7977918238481658), (190.42624775647235, 1.2101855989590893))


def reference_probes():
    return [pe.ProbeSpec(pe.ObjectSpec.from_paper(wn, alpha), pe.PlateMotion.from_paper(f, 3.0))
            for wn, alpha, f in ((10.0, 36.9, 14.0), (23.0, 50.0, 22.0), (33.0, 36.9, 26.0), (10.0, 50.0, 18.0))]


def _dense_from_blocks(geom, blocks):
    layout = grid_layout(geom)
    node_of = {int(s): k for k, s in enumerate(layout.slot)}
    n = geom.n_nodes
    full = np.zeros((n, n))
    for p, signs in enumerate(PARITY_SIGNS):
        basis = np.zeros((n, len(layout.quad)))
        for o, members in enumerate(layout.quad):
            for sign, member in zip(signs, members, strict=True):
                basis[node_of[int(member)], o] = 0.5 * sign
        full += basis @ blocks[p].T @ basis.T
    return full


@pytest.mark.parametrize("diameter", [0.08, 0.05])
def test_grid_layout_holds_every_joint_triplet_and_node(diameter):
    grid = grid_layout(disc_geometry(diameter))  # raises if a joint or triplet differs from the geometry's
    assert grid.masks.sum(axis=1).tolist() == [44, 44, 37, 37, 36, 36, 52]
    assert len(set(grid.slot.tolist())) == 52 and grid.quad.shape == (13, 4)


def test_grid_layout_refuses_a_geometry_it_does_not_match():
    geom = disc_geometry(0.08)
    with pytest.raises(AssertionError, match="links do not match"):
        grid_layout(dataclasses.replace(geom, links=geom.links[:-1]))


@pytest.mark.parametrize("omega_n_pi", [1.4, 10.0, 50.0])
def test_damper_blocks_are_the_dense_implicit_damper(omega_n_pi):
    params = build_params(pe.ObjectSpec.from_paper(omega_n_pi, 36.9))
    dense = implicit_damping_matrix(params, 2e-4)
    assert np.max(np.abs(_dense_from_blocks(params.geom, grid_damping_blocks(params, 2e-4)) - dense)) < 1e-13


def test_unknown_kernel_refused_and_named_in_the_cache_key():
    with pytest.raises(ValueError, match="unknown point-mass kernel 'v3'"):
        pe.make_physics("tilelink", kernel="v3")
    v1, v2 = pe.make_physics("tilelink"), pe.make_physics("tilelink", kernel="v2")
    assert "kernel" not in backend_tag(v1)  # caches of v1 keep their keys
    assert "kernel=v2" in backend_tag(v2)


def test_v2_omega_b_within_stderr_of_v1():
    specs = reference_probes()
    old = pe.make_physics("tilelink").run(specs)
    new = pe.make_physics("tilelink", kernel="v2").run(specs)
    for a, b in zip(old, new, strict=True):
        assert not a.unstable and not b.unstable
        assert a.stderr_deg_s > 0
        assert abs(b.omega_b_deg_s - a.omega_b_deg_s) <= a.stderr_deg_s, (a.spec, a.omega_b_deg_s, b.omega_b_deg_s)
    for a, (omega, se) in zip(old, V1_REFERENCE, strict=True):
        assert a.omega_b_deg_s == pytest.approx(omega, rel=1e-9)  # v1 is unchanged
        assert a.stderr_deg_s == pytest.approx(se, rel=1e-6)
    for b, (omega, se) in zip(new, V1_REFERENCE, strict=True):
        assert abs(b.omega_b_deg_s - omega) <= se


def test_v2_batch_repeats_single_runs_bit_for_bit():
    physics = pe.make_physics("tilelink", kernel="v2")
    specs = [dataclasses.replace(s, record_trace=True, settle_s=0.3, measure_s=0.5) for s in reference_probes()]
    batch = physics.run(specs)
    for spec, b in zip(specs, batch, strict=True):
        s = physics.run([spec])[0]
        assert s.trace.yaw.tobytes() == b.trace.yaw.tobytes()
        assert s.trace.centre_u.tobytes() == b.trace.centre_u.tobytes()
        assert (s.omega_b_deg_s, s.reason) == (b.omega_b_deg_s, b.reason)


def test_v2_still_plate_leaves_disc_still(cheese):
    physics = pe.make_physics("tilelink", kernel="v2")
    spec = pe.ProbeSpec(cheese, pe.PlateMotion(freq_hz=20.0, amp_rad=0.0, b_p=0.0), settle_s=0.3, measure_s=1.0,
                        record_trace=True)
    r = physics.run([spec])[0]
    assert not r.unstable and abs(r.omega_b_deg_s) < 0.01
    assert np.max(np.abs(r.trace.centre_u)) < 1e-6 and np.max(np.abs(r.trace.centre_v)) < 1e-6


def test_v2_huge_dt_is_unstable_with_a_reason_not_nan(cheese):
    with pytest.warns(UserWarning, match="above the largest time step measured stable"):
        physics = pe.make_physics("tilelink", dt=5e-3, kernel="v2")
    specs = [pe.ProbeSpec(pe.ObjectSpec.from_paper(w, 36.9), pe.PlateMotion.from_paper(25.0, 3.0), settle_s=0.2,
                          measure_s=0.3) for w in (1.4, 10.0, 40.0)]
    res = physics.run(specs)
    assert all(r.unstable and r.reason in ("non_finite", "runaway_energy", "left_plate", "overturned") for r in res)
    assert all(math.isfinite(r.omega_b_deg_s) and math.isfinite(r.stderr_deg_s) for r in res)
