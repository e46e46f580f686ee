"""Probes, comparisons and executor wrappers shared by tests/test_executor.py and tests/test_ray.py."""

from __future__ import annotations

import contextlib
import dataclasses

import plate_env as pe
from plate_env.executor import BackendSpec

POINTMASS = BackendSpec.of("tilelink")


def short_specs(n: int = 6, measure_s: float = 0.3) -> list[pe.ProbeSpec]:
    obj = pe.preset("cheese")
    return [pe.ProbeSpec(obj, pe.PlateMotion.from_paper(14.0 + 2 * k, 3.0), settle_s=0.2, measure_s=measure_s)
            for k in range(n)]


def same(a: list[pe.ProbeResult], b: list[pe.ProbeResult]) -> bool:
    """Equal in every field but the wall time (bit for bit in the floats)."""
    return [dataclasses.replace(r, wall_s=0.0) for r in a] == [dataclasses.replace(r, wall_s=0.0) for r in b]


class Interrupting:
    """Wraps an executor: Ctrl-C (KeyboardInterrupt) after ``after`` chunks were handed over."""

    name = "interrupting"

    def __init__(self, inner, after: int) -> None:
        self.inner, self.after = inner, after

    def map(self, backend, chunks):
        with contextlib.closing(self.inner.map(backend, chunks)) as it:
            for n, item in enumerate(it, start=1):
                yield item
                if n >= self.after:
                    raise KeyboardInterrupt

    def close(self) -> None:
        self.inner.close()


class Counting:
    """Wraps an executor: records how many probes each call of map was given."""

    name = "counting"

    def __init__(self, inner) -> None:
        self.inner, self.given = inner, []

    def map(self, backend, chunks):
        self.given.append(sum(map(len, chunks)))
        yield from self.inner.map(backend, chunks)

    def close(self) -> None:
        self.inner.close()
