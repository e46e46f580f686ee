"""Physics backends behind one interface: ``make_physics(name, **options).run(probes)``."""

from __future__ import annotations

from plate_env.core.probe import ProbeResult, ProbeSpec, YawTrace
from plate_env.physics.interface import Physics

PHYSICS_NAMES = ("tilelink", "pybullet", "atlas")


def make_physics(name: str, **options) -> Physics:
    """Create a physics backend by name; options go to its constructor.

    ``"tilelink"``: the paper's model (``model="pointmass"`` default, ``"rigid"`` or ``"rigid_limit"``), batched
    in numba.
    ``"pybullet"``: a PyBullet soft-body sheet on a kinematic plate (options: dt, n_layer, n_workers, ...).
    ``"atlas"``: the response atlas of another backend served as physics (microsecond probes, for RL training).
    """
    if name == "tilelink":
        from plate_env.physics.tilelink import TileLinkPhysics

        return TileLinkPhysics(**options)
    if name == "pybullet":
        from plate_env.physics.pybullet_sheet import PyBulletPhysics

        return PyBulletPhysics(**options)
    if name == "atlas":
        from plate_env.physics.atlas_physics import AtlasPhysics

        return AtlasPhysics(**options)
    raise ValueError(f"unknown physics {name!r}; choose one of {PHYSICS_NAMES}")


__all__ = ["PHYSICS_NAMES", "Physics", "ProbeResult", "ProbeSpec", "YawTrace", "make_physics"]
