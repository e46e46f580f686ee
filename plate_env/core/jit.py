"""When the numba kernels of the hot numpy paths (:mod:`plate_env.core.grid_kernels`) serve: after a process has
asked for them :data:`WARM_CALLS` times.

Importing numba and loading the kernels from its disk cache costs ~0.5-1 s (a first use on a machine compiles
them, seconds more), more than a short session spends in the paths they speed up (an env's first episodes, one
``plate-env fit``). So each hot path asks :func:`kernels` on every call and runs its numpy code while it answers
None; the kernels load on the :data:`WARM_CALLS`-th request of the process (RL training, a benchmark, a batch of
fits). Both give the same floats (tests/test_grid_kernels.py), so when the switch happens changes no number.
``PLATE_ENV_JIT=0`` keeps the numpy code, ``PLATE_ENV_JIT=1`` loads the kernels at the first request.
"""

from __future__ import annotations

import os
from types import ModuleType

#: Requests of a process before the kernels load (~3 per probe: an env's first ~7 episodes of ~10 probes).
WARM_CALLS = 200

_state: dict = {"calls": 0, "module": None, "forced": None}


def kernels() -> ModuleType | None:
    """:mod:`plate_env.core.grid_kernels` once this process has asked :data:`WARM_CALLS` times, else None (the
    caller runs its numpy code)."""
    mod = _state["module"]
    if mod is not None:
        return mod if _state["forced"] is not False else None
    forced = _state["forced"]
    if forced is False:
        return None
    setting = os.environ.get("PLATE_ENV_JIT", "")
    if setting == "0" and forced is None:
        return None
    _state["calls"] += 1
    if forced is None and setting != "1" and _state["calls"] < WARM_CALLS:
        return None
    from plate_env.core import grid_kernels

    _state["module"] = grid_kernels
    return grid_kernels


def force(on: bool | None) -> None:
    """Use the kernels always (True), never (False), or as :func:`kernels` decides (None): for tests comparing the
    two paths."""
    _state["forced"] = on
