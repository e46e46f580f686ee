"""Layer 5, the Gymnasium environment ``PlateRotation-v0`` (:class:`PlateRotationEnv`, in
:mod:`~plate_env.env.rotation`), its vector and Stable-Baselines3 forms (:mod:`~plate_env.env.vector`,
:mod:`~plate_env.env.sb3`), the observation/action codec (:mod:`~plate_env.env.codec`), rendering
(:mod:`~plate_env.env.render`), the probing-agent protocol (:mod:`~plate_env.env.protocol`) and the one episode loop
(:mod:`~plate_env.env.episode`)."""

from plate_env.env.codec import N_FEATURES, Codec
from plate_env.env.rotation import DEFAULT_MAX_PROBES, RESET_OPTIONS, PlateRotationEnv

__all__ = ["DEFAULT_MAX_PROBES", "N_FEATURES", "RESET_OPTIONS", "Codec", "PlateRotationEnv"]
