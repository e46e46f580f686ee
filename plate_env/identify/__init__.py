"""Layer 3, identification: from probes to omega_n_hat with its uncertainty.

The paper's Lorentzian fit (:mod:`~plate_env.identify.fitting`) and its Eq. (10) calibration
(:mod:`~plate_env.identify.calibration`), forward models (:mod:`~plate_env.identify.forward`), the posterior
(:mod:`~plate_env.identify.inference`), the estimate (:mod:`~plate_env.identify.estimate`) and :func:`identify`,
the one entry point (:mod:`~plate_env.identify.api`). Imports only core, surrogate and physics.

The names below load :mod:`~plate_env.identify.api` on first use, so that a module of this package (the env's
:mod:`~plate_env.identify.estimate`) imports without the posterior's and the fits' modules (``gym.make``'s time).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from plate_env.identify.api import METHODS, identify, identify_lorentz, offset_intervals, positive_intervals

__all__ = ["METHODS", "identify", "identify_lorentz", "offset_intervals", "positive_intervals"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        value = getattr(importlib.import_module("plate_env.identify.api"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'plate_env.identify' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
