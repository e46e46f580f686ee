"""PyBullet backend: a two-layer tetrahedral mass-spring sheet on a driven plate (deformable world).

pybullet itself is imported only when a scene is built.
"""

from plate_env.physics.pybullet_sheet.backend import PyBulletPhysics
from plate_env.physics.pybullet_sheet.scene import SheetConfig

__all__ = ["PyBulletPhysics", "SheetConfig"]
