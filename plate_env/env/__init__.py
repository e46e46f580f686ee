"""Layer 5, the Gymnasium environment ``PlateRotation-v0`` (:class:`PlateRotationEnv`, in
:mod:`~plate_env.env.rotation`), made of parts: its checked arguments :class:`EnvConfig` (:mod:`~plate_env.env.config`),
the physics backend, the identification task (:mod:`~plate_env.env.task`), the observation/action codec
(:mod:`~plate_env.env.codec`) and the episode state (:mod:`~plate_env.env.state`), which the single and the vector
env step alike; its vector and Stable-Baselines3 forms (:mod:`~plate_env.env.vector`, :mod:`~plate_env.env.sb3`),
the info schema (:mod:`~plate_env.env.info`), rendering (:mod:`~plate_env.env.render`), the probing-agent protocol
(:mod:`~plate_env.env.protocol`) and the one episode loop (:mod:`~plate_env.env.episode`).

The names below load their module on first use, so that importing :mod:`~plate_env.env.protocol` (the agents, the
command line) does not import gymnasium."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from plate_env.core.setup import DEFAULT_MAX_PROBES
    from plate_env.env.codec import N_FEATURES, Codec
    from plate_env.env.config import EnvConfig
    from plate_env.env.rotation import RESET_OPTIONS, PlateRotationEnv

#: Public name -> the module that defines it.
_LAZY = {"N_FEATURES": "plate_env.env.codec", "Codec": "plate_env.env.codec", "EnvConfig": "plate_env.env.config",
         "DEFAULT_MAX_PROBES": "plate_env.core.setup", "RESET_OPTIONS": "plate_env.env.rotation",
         "PlateRotationEnv": "plate_env.env.rotation"}

__all__ = ["DEFAULT_MAX_PROBES", "N_FEATURES", "RESET_OPTIONS", "Codec", "EnvConfig", "PlateRotationEnv"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'plate_env.env' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
