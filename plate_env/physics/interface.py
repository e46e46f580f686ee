"""The one small interface every physics backend implements (:class:`Physics`); the values that cross it live
in :mod:`plate_env.core.probe`."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

from plate_env.core.probe import ProbeResult, ProbeSpec


@runtime_checkable
class Physics(Protocol):
    """A physics backend: runs probes, nothing else."""

    name: str

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        """Simulate every probe (batched where the backend can) and return one result per probe, in order."""
        ...

    def close(self) -> None:
        """Release resources (processes, clients). Safe to call twice."""
        ...

    # Optional: ``check(probes) -> None`` raising ProbeRefused for probes the backend cannot answer (see
    # refuse_early); ``run`` calls it before any work.


def refuse_early(physics: Physics, probes: Sequence[ProbeSpec]) -> None:
    """Raise :class:`ProbeRefused` for the first of ``probes`` that ``physics`` cannot answer, before any work.

    Backends with limits beyond ProbeSpec's own checks (the atlas's domain, a step-count limit) define
    ``check(probes)``; others accept every valid ProbeSpec.
    """
    check = getattr(physics, "check", None)
    if check is not None:
        check(probes)


def warn_above_stable_dt(dt: float, limit: float, what: str, source: str) -> None:
    """Warn (UserWarning naming dt) when ``dt`` exceeds the largest time step measured stable for ``what``."""
    if dt > limit * (1 + 1e-9):
        import warnings

        warnings.warn(f"dt = {dt:g} s is above the largest time step measured stable for {what} ({limit:g} s, "
                      f"{source}): expect probes to end unstable (runaway_energy) because of dt", stacklevel=3)
