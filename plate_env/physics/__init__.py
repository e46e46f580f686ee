"""Physics backends behind one interface: ``make_physics(name, **options).run(probes)``."""

from __future__ import annotations

from plate_env.physics.base import Physics, ProbeResult, ProbeSpec, YawTrace

PHYSICS_NAMES = ("tilelink",)


def make_physics(name: str, **options) -> Physics:
    """Create a physics backend by name (``"tilelink"``); options go to its constructor."""
    if name == "tilelink":
        from plate_env.physics.tilelink import TileLinkPhysics

        return TileLinkPhysics(**options)
    raise ValueError(f"unknown physics {name!r}; choose one of {PHYSICS_NAMES}")


__all__ = ["PHYSICS_NAMES", "Physics", "ProbeResult", "ProbeSpec", "YawTrace", "make_physics"]
