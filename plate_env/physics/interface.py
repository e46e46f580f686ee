"""The one small interface every physics backend implements (:class:`Physics`); the values that cross it live
in :mod:`plate_env.core.probe`."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

from plate_env.core.probe import ProbeResult, ProbeSpec


@runtime_checkable
class Physics(Protocol):
    """A physics backend: runs probes, nothing else. Every member is declared here (no caller reads a backend's
    attributes by ``getattr``); :class:`PhysicsBackend` gives the optional ones their defaults.

    - ``name``: the backend's registry name (``tilelink``, ``pybullet``, ``atlas``);
    - ``source``: the physics the results come from (the backend's own name, or the physics an atlas was built of);
    - ``model``: the model within the source (a tile-link model; ``pybullet``; an atlas's model);
    - ``dt``: the integration time step, s (None for a backend that does not integrate: the atlas);
    - ``sequence_len``: probes of one object run in one scene, the disc keeping its state (1: a fresh scene each);
    - ``check(probes)``: raise :class:`~plate_env.core.probe.ProbeRefused` for a probe the backend cannot answer,
      before any work (:func:`refuse_early`);
    - ``describe()``: the backend's identity and every setting that changes a result, for cache keys
      (:func:`plate_env.run.sweeps.backend_tag`) and provenance.
    """

    name: str
    source: str
    model: str
    dt: float | None
    sequence_len: int

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        """Simulate every probe (batched where the backend can) and return one result per probe, in order."""
        ...

    def check(self, probes: Sequence[ProbeSpec]) -> None:
        """Refuse (ProbeRefused) the first probe the backend cannot answer, before any work."""
        ...

    def describe(self) -> dict[str, Any]:
        """``{"name", "source", "model", "settings"}``: the identity and the settings that change a result."""
        ...

    def close(self) -> None:
        """Release resources (processes, clients). Safe to call twice."""
        ...


class PhysicsBackend:
    """The shipped backends' base: :class:`Physics`'s optional members with their defaults.

    A subclass sets ``name`` (class attribute), ``source`` and ``model`` (by default its ``name``), and lists in
    :attr:`SETTINGS` the attributes whose values change a result; :meth:`describe` reports them in that order (the
    order of the cache key, :func:`plate_env.run.sweeps.backend_tag`, which leaves out values equal to their
    historic defaults so that caches made before a setting existed stay valid).
    """

    name: str = ""
    #: The attributes whose values change a result, in cache-key order (a subset of
    #: :data:`plate_env.run.sweeps.TAG_SETTINGS`).
    SETTINGS: tuple[str, ...] = ()
    dt: float | None = None
    sequence_len: int = 1

    @property
    def source(self) -> str:
        return self.name

    @property
    def model(self) -> str:
        return self.name

    def check(self, probes: Sequence[ProbeSpec]) -> None:
        """Accept every valid ProbeSpec (a backend with limits of its own overrides this)."""

    def describe(self) -> dict[str, Any]:
        """``{"name", "source", "model", "settings"}``: ``settings`` maps each of :attr:`SETTINGS` to its value."""
        return {"name": self.name, "source": self.source, "model": self.model,
                "settings": {k: getattr(self, k) for k in self.SETTINGS}}

    def close(self) -> None:
        """Nothing to release (a backend holding processes or clients overrides this)."""


def refuse_early(physics: Physics, probes: Sequence[ProbeSpec]) -> None:
    """Raise :class:`ProbeRefused` for the first of ``probes`` that ``physics`` cannot answer, before any work.

    Backends with limits beyond ProbeSpec's own checks (the atlas's domain, a step-count limit) override
    ``check(probes)``; :class:`PhysicsBackend`'s accepts every valid ProbeSpec.
    """
    physics.check(probes)


def warn_above_stable_dt(dt: float, limit: float, what: str, source: str) -> None:
    """Warn (UserWarning naming dt) when ``dt`` exceeds the largest time step measured stable for ``what``."""
    if dt > limit * (1 + 1e-9):
        import warnings

        warnings.warn(f"dt = {dt:g} s is above the largest time step measured stable for {what} ({limit:g} s, "
                      f"{source}): expect probes to end unstable (runaway_energy) because of dt", stacklevel=3)
