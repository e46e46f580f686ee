"""Physics backends behind one interface: ``make_physics(name, **options).run(probes)``."""

from __future__ import annotations

from typing import Any

from plate_env.core.probe import ProbeResult, ProbeSpec, YawTrace
from plate_env.core.registry import Registry
from plate_env.physics.interface import Physics

#: The physics backends, by name (the one list: the env, the command line, the executor read it).
PHYSICS = Registry("physics", {"tilelink": "plate_env.physics.tilelink:TileLinkPhysics",
                               "pybullet": "plate_env.physics.pybullet_sheet:PyBulletPhysics",
                               "atlas": "plate_env.physics.atlas_physics:AtlasPhysics"})
PHYSICS_NAMES = PHYSICS.names


def make_physics(name: str, **options: Any) -> Physics:
    """Create a physics backend by name (:data:`PHYSICS`); options go to its constructor.

    ``"tilelink"``: the paper's model (``model="pointmass"`` default, ``"rigid"``, ``"rigid_limit"``,
    ``"rigid_fast"``), batched in numba.
    ``"pybullet"``: a PyBullet soft-body sheet on a kinematic plate (options: dt, n_layer, n_workers, ...).
    ``"atlas"``: the response atlas of another backend served as physics (microsecond probes, for RL training).
    """
    physics: Physics = PHYSICS.load(name)(**options)
    return physics


__all__ = ["PHYSICS", "PHYSICS_NAMES", "Physics", "ProbeResult", "ProbeSpec", "YawTrace", "make_physics"]
