"""plate-env: read a thin deformable object's bending stiffness from how fast it turns on a vibrating plate.

Light to import: numba, pybullet, matplotlib and torch load only when the code that needs them runs.
"""

from plate_env.motion import PlateMotion
from plate_env.objects import PRESETS, ObjectSpec, preset
from plate_env.physics import PHYSICS_NAMES, ProbeResult, ProbeSpec, make_physics

__version__ = "0.1.0"


def _register() -> None:
    from gymnasium.envs.registration import register, registry

    for env_id in ("PlateRotation-v0", "plate_env/PlateRotation-v0"):
        if env_id not in registry:
            register(id=env_id, entry_point="plate_env.env:PlateRotationEnv",
                     vector_entry_point="plate_env.vector:PlateRotationVectorEnv")


_register()

__all__ = ["PHYSICS_NAMES", "PRESETS", "ObjectSpec", "PlateMotion", "ProbeResult", "ProbeSpec", "__version__",
           "make_physics", "preset"]
