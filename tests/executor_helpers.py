"""Probes, comparisons and executor wrappers shared by tests/test_executor.py and tests/test_ray.py."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import threading
import time

import plate_env as pe
from plate_env.run.executor import BackendSpec

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

    def map(self, fn, items):
        with contextlib.closing(self.inner.map(fn, items)) as it:
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

    def map(self, fn, items):
        self.given.append(sum(map(len, items)))
        yield from self.inner.map(fn, items)

    def close(self) -> None:
        self.inner.close()


def run_killing_one(find_pids, run, settle_s: float = 0.0, timeout_s: float = 120.0):
    """``run()`` while a thread SIGKILLs the first process ``find_pids()`` names (``settle_s`` after it first names
    any); returns ``(run's result, [killed pid])``."""
    killed: list[int] = []
    stop = threading.Event()

    def kill() -> None:
        deadline = time.monotonic() + timeout_s
        while not stop.is_set() and time.monotonic() < deadline:
            pids = find_pids()
            if pids:
                if settle_s:
                    time.sleep(settle_s)
                    pids = find_pids() or pids
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])
                return
            time.sleep(0.01)

    killer = threading.Thread(target=kill)
    killer.start()
    try:
        out = run()
    finally:
        stop.set()
        killer.join()
    return out, killed
