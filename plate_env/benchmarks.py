"""Object sets and probe grids shared by the experiment scripts (calibration, atlas, evaluation, comparisons).

Calibration and atlas grid objects never coincide with the held-out objects used to score identification.
"""

from __future__ import annotations

import numpy as np

from plate_env.motion import PlateMotion
from plate_env.objects import ObjectSpec
from plate_env.physics.base import ProbeSpec

#: Objects the Eq. (10) calibration is fitted on (omega_n in pi rad/s, alpha in degrees).
CALIBRATION_OMEGAS_PI = (3.5, 5.0, 7.0, 10.0, 13.0, 17.0, 23.0, 28.0, 33.0)
CALIBRATION_ALPHAS_DEG = (30.0, 36.9, 45.0, 56.3)
#: Held-out objects: omega_n and alpha values used by no calibration and no atlas grid point.
HELD_OUT_OMEGAS_PI = (4.2, 6.0, 8.5, 11.5, 15.0, 20.0, 25.5, 30.5)
HELD_OUT_ALPHAS_DEG = (33.0, 41.0, 50.0)
#: The atlas grid.
ATLAS_F_HZ = tuple(float(f) for f in np.arange(10.0, 40.01, 1.0))
ATLAS_AMPS_DEG = (3.0, 12.0)
ATLAS_OMEGAS_PI = tuple(float(w) for w in np.round(np.geomspace(1.4, 40.0, 16), 3))
ATLAS_ALPHAS_DEG = (28.0, 36.0, 44.0, 52.0, 60.0)
#: The paper's sweep: 10-40 Hz.
SWEEP_F_HZ = tuple(float(f) for f in np.arange(10.0, 40.01, 1.0))


def objects(omegas_pi, alphas_deg) -> list[ObjectSpec]:
    """Every combination, in the paper's units."""
    return [ObjectSpec.from_paper(w, a) for w in omegas_pi for a in alphas_deg]


def sweep_specs(obj: ObjectSpec, freqs_hz, a_p_deg: float, b_p_mm: float = 3.0, **kw) -> list[ProbeSpec]:
    """A frequency sweep of one object at one plate amplitude."""
    return [ProbeSpec(obj, PlateMotion.from_paper(float(f), a_p_deg, b_p_mm), **kw) for f in freqs_hz]
