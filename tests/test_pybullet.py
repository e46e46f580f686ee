"""PyBullet sheet backend: omega_n calibration, sign, determinism, instability detection, pool == serial."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.physics.base import REASONS, ProbeSpec
from plate_env.physics.pybullet_sheet import PyBulletPhysics, SheetConfig
from plate_env.physics.pybullet_sheet.calibrate import calibrated_k, ringdown_omega_n
from plate_env.physics.pybullet_sheet.mesh import make_sheet
from plate_env.physics.pybullet_sheet.scene import Client

pytest.importorskip("pybullet")


def _probe(obj: pe.ObjectSpec, f: float = 25.0, a_deg: float = 3.0, b_mm: float = 3.0) -> ProbeSpec:
    return ProbeSpec(obj, pe.PlateMotion.from_paper(f, a_deg, b_mm, ramp_s=0.1), settle_s=0.2, measure_s=0.3)


def test_mesh_equal_area_inertia() -> None:
    m = make_sheet(50, 0.08, 0.002)
    r2 = (m.nodes[:50, :2] ** 2).sum(axis=1).mean()
    assert r2 == pytest.approx(0.04 ** 2 / 2, rel=1e-9)
    assert m.n_nodes == 100


@pytest.mark.parametrize("omega_pi", [5.0, 33.0])
def test_built_omega_n_within_5_percent(omega_pi: float) -> None:
    obj = pe.ObjectSpec.from_paper(omega_pi, 36.9)
    cfg = SheetConfig()
    client = Client()
    try:
        w = ringdown_omega_n(client, obj, calibrated_k(obj, cfg)[0], cfg)
    finally:
        client.close()
    assert abs(w / obj.omega_n - 1) < 0.05


def test_rotation_sign_follows_b_p() -> None:
    phys = PyBulletPhysics(sequence_len=1)
    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    try:
        pos, neg = phys.run([_probe(obj, f=18.0, b_mm=3.0), _probe(obj, f=18.0, b_mm=-3.0)])
    finally:
        phys.close()
    assert pos.omega_b_deg_s > 30 and neg.omega_b_deg_s < -30


def test_deterministic_and_finite() -> None:
    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    probes = [_probe(obj, f=20.0)]
    a = PyBulletPhysics().run(probes)
    b = PyBulletPhysics().run(probes)
    assert [r.omega_b_deg_s for r in a] == [r.omega_b_deg_s for r in b]
    assert all(math.isfinite(r.omega_b_deg_s) and math.isfinite(r.stderr_deg_s) for r in a)


def test_huge_dt_is_flagged_unstable() -> None:
    phys = PyBulletPhysics(dt=5e-3, k_elastic=100.0)
    obj = pe.ObjectSpec.from_paper(33.0, 36.9)
    (r,) = phys.run([_probe(obj)])
    phys.close()
    phys.close()  # safe twice
    assert r.unstable and r.reason in REASONS
    assert np.isfinite([r.omega_b_deg_s, r.stderr_deg_s]).all()


@pytest.mark.slow
def test_pool_equals_serial() -> None:
    obj1 = pe.ObjectSpec.from_paper(10.0, 36.9)
    obj2 = pe.ObjectSpec.from_paper(23.0, 56.3)
    probes = [_probe(obj1, f=20.0), _probe(obj2, f=22.0), _probe(obj1, f=26.0)]
    serial = PyBulletPhysics(n_workers=1).run(probes)
    pool = PyBulletPhysics(n_workers=2)
    try:
        par = pool.run(probes)
    finally:
        pool.close()
    assert [r.omega_b_deg_s for r in serial] == [r.omega_b_deg_s for r in par]
    assert [r.reason for r in serial] == [r.reason for r in par]
