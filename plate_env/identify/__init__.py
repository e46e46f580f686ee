"""Layer 3, identification: from probes to omega_n_hat with its uncertainty.

The paper's Lorentzian fit (:mod:`~plate_env.identify.fitting`) and its Eq. (10) calibration
(:mod:`~plate_env.identify.calibration`), forward models (:mod:`~plate_env.identify.forward`), the posterior
(:mod:`~plate_env.identify.inference`), the estimate (:mod:`~plate_env.identify.estimate`) and :func:`identify`,
the one entry point (:mod:`~plate_env.identify.api`). Imports only core, surrogate and physics.
"""

from plate_env.identify.api import METHODS, identify, identify_lorentz, offset_intervals, positive_intervals

__all__ = ["METHODS", "identify", "identify_lorentz", "offset_intervals", "positive_intervals"]
