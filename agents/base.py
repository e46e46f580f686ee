"""The agent protocol the shipped agents implement (defined in the library core, :mod:`plate_env.protocol`)."""

from __future__ import annotations

from plate_env.protocol import Agent, Probe, ProbeContext

__all__ = ["Agent", "Probe", "ProbeContext"]
