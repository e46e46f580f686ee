"""The physics interface (issue 35: "the physics interface is informal"): every backend declares the members
callers use (no getattr), and its cache key is built from ``describe()``."""

from __future__ import annotations

import pytest

import plate_env as pe
from plate_env.core.probe import ProbeRefused
from plate_env.physics import PHYSICS_NAMES, make_physics
from plate_env.physics.interface import Physics, PhysicsBackend
from plate_env.run.sweeps import TAG_SETTINGS, backend_tag

# The tags the committed caches were keyed with (experiments/cache/*.jsonl, first field of each key): a change of
# the interface that moved one would orphan every cached probe of that backend.
_POINTMASS_TAIL = ("config=PointMassConfig(k_inplane=300.0, zeta_inplane=0.2, zeta_bending=0.1),rigid_config="
                   "RigidTileConfig(k_inplane=300.0, zeta_inplane=0.2, zeta_bending=0.1, omega_rigid={w}, "
                   "zeta_rigid=1.0, iterations={it}, contact_points=4, fold_angle=2.6179938779914944, "
                   "fold_tile_w=-0.2, energy_rel_tol=0.1, energy_abs_tol=0.0002, block_refresh=10),contact="
                   "ContactLaw(k=47215510.42764483, c=7.65, v_transition=0.1)")
COMMITTED_TAGS = {
    ("tilelink", "pointmass"): "tilelink,model=pointmass,dt=0.0002," + _POINTMASS_TAIL.format(w=5000.0, it=2),
    ("tilelink", "rigid_fast"): "tilelink,model=rigid_fast,dt=2.5e-05," + _POINTMASS_TAIL.format(w=40000.0, it=1),
    ("pybullet", None): ("pybullet,dt=0.0004,config=SheetConfig(n_layer=91, thickness=0.002, dt=0.0004, "
                         "margin=0.0005, damping_time=0.0002, bending_ratio=1.0, plate_half=0.1, "
                         "plate_half_thick=0.005, record_every_s=0.002, slip_limit=0.01)"),
    ("atlas", None): "atlas,model=pointmass",
}


@pytest.mark.parametrize(("name", "model"), sorted(COMMITTED_TAGS, key=str))
def test_the_cache_key_of_each_backend_is_the_one_its_committed_caches_carry(name, model):
    p = make_physics(name, **({} if model is None else {"model": model}))
    try:
        assert backend_tag(p) == COMMITTED_TAGS[(name, model)]
    finally:
        p.close()


@pytest.mark.parametrize("name", PHYSICS_NAMES)
def test_every_backend_declares_the_interface(name):
    p = make_physics(name)
    try:
        assert isinstance(p, Physics) and isinstance(p, PhysicsBackend)
        d = p.describe()
        assert d["name"] == p.name == name and d["source"] == p.source and d["model"] == p.model
        assert set(d["settings"]) <= set(TAG_SETTINGS)
        assert p.dt is None or p.dt > 0
        assert isinstance(p.sequence_len, int) and p.sequence_len >= 1
    finally:
        p.close()


def test_an_atlas_names_the_physics_it_was_built_of():
    p = make_physics("atlas", source="pybullet", model="pybullet")
    assert (p.name, p.source, p.model, p.dt) == ("atlas", "pybullet", "pybullet", None)


def test_a_setting_the_cache_key_does_not_list_is_refused():
    class Unlisted(PhysicsBackend):
        name = "tilelink"
        SETTINGS = ("dt", "stiffness_scale")
        dt, stiffness_scale = 2e-4, 2.0

    with pytest.raises(ValueError, match="stiffness_scale"):
        backend_tag(Unlisted())


def test_a_backends_default_check_accepts_and_its_own_refuses():
    spec = pe.ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(20.0, 3.0), settle_s=500.0)
    PhysicsBackend().check([spec])  # the base accepts every valid probe
    tl = make_physics("tilelink", model="rigid_fast")  # 500 s at 2.5e-5 s: 2e7 steps, over MAX_PROBE_STEPS
    with pytest.raises(ProbeRefused, match="steps"):
        tl.check([spec])
