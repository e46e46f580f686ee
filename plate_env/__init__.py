"""plate-env: read a thin deformable object's bending stiffness from how fast it turns on a vibrating plate.

Light to import: numba, pybullet, matplotlib and torch load only when the code that needs them runs; gymnasium
loads with the package, which registers its env ids (:data:`ENV_IDS`).

The package is layered, each layer importing only the ones below it: :mod:`plate_env.core` ->
:mod:`plate_env.surrogate` -> :mod:`plate_env.physics` -> :mod:`plate_env.identify` -> :mod:`plate_env.run` ->
:mod:`plate_env.env` -> :mod:`plate_env.bench` -> :mod:`plate_env.build`, with the command line and plots at the
edge.
"""

from __future__ import annotations

from plate_env.core.motion import PlateMotion
from plate_env.core.objects import PRESETS, ObjectSpec, preset
from plate_env.env.ids import ENV_IDS, FAITHFUL_IDS, register
from plate_env.physics import PHYSICS_NAMES, ProbeResult, ProbeSpec, make_physics

__version__ = "0.1.0"

# As panda-gym does: importing the package registers its ids (ENV_IDS) with gymnasium, whatever was imported before
# or after (no import hook: a hook that waited for gymnasium's import was used up by libraries that probe for it
# first, issue 41). It imports gymnasium, ~80 ms of start-up (experiments/bench_startup.py).
register()

__all__ = ["ENV_IDS", "FAITHFUL_IDS", "PHYSICS_NAMES", "PRESETS", "ObjectSpec", "PlateMotion", "ProbeResult",
           "ProbeSpec", "__version__", "make_physics", "preset"]
