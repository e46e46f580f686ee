"""PyBullet sheet backend: omega_n calibration, sign, determinism, instability detection, pool == serial."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.core.probe import REASONS, ProbeSpec
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


def test_mesh_triangles_are_scipys_delaunay_and_a_warm_process_imports_no_scipy_spatial(tmp_path) -> None:
    """The sheet's triangles come from the disk cache once computed (scipy.spatial costs 1-2 s of import on a loaded
    machine): the same simplices as ``Delaunay``, and a second process builds the mesh without importing it."""
    import os
    import subprocess
    import sys

    from scipy.spatial import Delaunay

    from plate_env.physics.pybullet_sheet.mesh import delaunay_triangles, sunflower_points

    pts = sunflower_points(91, 0.04)
    assert np.array_equal(delaunay_triangles(pts), Delaunay(pts).simplices)
    code = ("import sys; from plate_env.physics.pybullet_sheet.mesh import make_sheet; "
            "m = make_sheet(91, 0.08, 0.002); print(int(m.tets.sum()), 'scipy.spatial' in sys.modules)")
    env = dict(os.environ, PLATE_ENV_CACHE_DIR=str(tmp_path))
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
            .split() for _ in range(2)]
    assert runs[0] == [runs[1][0], "True"] and runs[1][1] == "False"
    assert runs[0][0] == str(int(make_sheet(91, 0.08, 0.002).tets.sum()))


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


def test_the_stiffness_calibration_ignores_friction_and_is_shared_across_alpha(monkeypatch) -> None:
    """The ring-down touches nothing, so alpha cannot change it (the same omega_n to the last bit at alpha 26 and 64
    deg), and objects differing in alpha only share one calibration: an env's random objects and an atlas's alpha
    axis ran one ring-down series per alpha before."""
    from plate_env.physics.pybullet_sheet import calibrate

    cfg = SheetConfig()
    a, b = pe.ObjectSpec.from_paper(12.0, 26.0), pe.ObjectSpec.from_paper(12.0, 64.0)
    client = Client()
    try:
        k = calibrate.k_for_omega_n(a, cfg)
        assert ringdown_omega_n(client, a, k, cfg) == ringdown_omega_n(client, b, k, cfg)
    finally:
        client.close()
    calls = []
    monkeypatch.setattr(calibrate, "_calibrated_k", lambda obj, *rest: calls.append(obj) or (1.0, obj.omega_n))
    assert calibrate.calibrated_k(a, cfg) == calibrate.calibrated_k(b, cfg)
    assert calls[0] == calls[1] and calls[0].alpha == calibrate.RINGDOWN_ALPHA


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
    with pytest.warns(UserWarning, match="dt = 0.005 s is above the largest time step measured stable"):
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


# ------------------------------------------------------------------------------------- issue 16, defects 12 and 13
def test_nothing_from_pybullet_on_stdout(capfd) -> None:
    phys = PyBulletPhysics(n_layer=30, k_elastic=100.0)
    try:
        phys.run([_probe(pe.ObjectSpec.from_paper(10.0, 36.9), f=18.0)])
    finally:
        phys.close()
    out, _ = capfd.readouterr()  # file descriptor 1, where PyBullet's C code printed "Nodes: 60 ..."
    assert out == ""


def test_cli_json_on_pybullet_is_one_json_document() -> None:
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "plate_env", "probe", "--physics", "pybullet", "--freq", "18",
                           "--settle", "0.1", "--measure", "0.2", "--json"], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["f_p_hz"] == 18.0  # nothing else on stdout


def test_probe_placement_is_honoured() -> None:
    from dataclasses import replace

    obj = pe.ObjectSpec.from_paper(10.0, 36.9)
    base = ProbeSpec(obj, pe.PlateMotion.from_paper(18.0, 3.0), settle_s=0.1, measure_s=0.3, record_trace=True)
    moved = replace(base, initial_yaw=0.6, initial_offset=(3e-4, -2e-4))
    phys = PyBulletPhysics(n_layer=30, k_elastic=100.0)
    try:
        assert phys.units([base, moved, moved, base]) == [[base], [moved, moved], [base]]
        r0, r1, r2 = (phys.run([s])[0] for s in (base, moved, moved))
    finally:
        phys.close()
    c0 = np.array([r0.trace.centre_u[0], r0.trace.centre_v[0]])  # the centred sheet's start (mesh centroid)
    turn = np.array([[math.cos(0.6), -math.sin(0.6)], [math.sin(0.6), math.cos(0.6)]])
    assert [r1.trace.centre_u[0], r1.trace.centre_v[0]] == pytest.approx(turn @ c0 + [3e-4, -2e-4], abs=1e-6)
    assert r1.omega_b_deg_s != r0.omega_b_deg_s  # another start, another run
    assert r2.omega_b_deg_s == r1.omega_b_deg_s  # the same start repeats exactly


def test_env_repeats_on_pybullet_are_placed_at_random() -> None:
    from plate_env.env.rotation import PlateRotationEnv

    env = PlateRotationEnv(physics="pybullet", method="lorentz", max_probes=3, settle_s=0.1,
                           measure_range_s=(0.1, 0.3), physics_options=dict(n_layer=30, k_elastic=100.0))
    env.reset(seed=0)
    action = np.array([-0.47, -1.0, 1.0, -1.0], np.float32)  # 17 Hz, 3 deg, 0.3 s: the same probe twice
    first = env.step(action)[4]["last_probe"]
    second = env.step(action)[4]["last_probe"]
    env.close()
    assert first["f_p_hz"] == second["f_p_hz"]
    assert first["omega_b_deg_s"] != second["omega_b_deg_s"]  # every repeat used to be the same centred run
