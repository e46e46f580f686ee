"""``physics="tilelink"``: the paper's own simulation model (Section 3.2), batched in numba."""

from plate_env.physics.tilelink.backend import TileLinkPhysics

__all__ = ["TileLinkPhysics"]
