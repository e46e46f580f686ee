"""When the numba kernels of the hot numpy paths (:mod:`plate_env.core.grid_kernels`) serve: in a process that has
ended :data:`WARM_EPISODES` env episodes.

Importing numba and loading the kernels from its disk cache costs ~0.5-1 s (a first use on a machine compiles
them, seconds more): more than one ``plate-env fit``, a bayes decision or an env's first episodes spend in the
paths they speed up, less than a process that runs many episodes (RL training, a benchmark) saves. So the hot paths
ask :func:`kernels` on every call and run their numpy code while it answers None; the env reports each episode end
(:func:`episode_ended`), and the :data:`WARM_EPISODES`-th loads the kernels there and then (at an episode end, not
inside a step or an agent's decision). Processes that never run episodes keep the numpy code unless numba's kernels
are asked for. Both give the same floats (tests/test_grid_kernels.py), so when the switch happens changes no number.
``PLATE_ENV_JIT=0`` keeps the numpy code, ``PLATE_ENV_JIT=1`` loads the kernels at the first request.
"""

from __future__ import annotations

import os
from types import ModuleType

#: Env episode ends of a process before the kernels load (an RL or benchmark process; a session of a few episodes
#: never pays numba's start).
WARM_EPISODES = 5

_state: dict = {"episodes": 0, "module": None, "forced": None}


def _setting() -> str:
    return os.environ.get("PLATE_ENV_JIT", "")


def _load() -> ModuleType:
    from plate_env.core import grid_kernels

    _state["module"] = grid_kernels
    return grid_kernels


def kernels() -> ModuleType | None:
    """:mod:`plate_env.core.grid_kernels` once loaded (:func:`episode_ended`, ``PLATE_ENV_JIT=1`` or
    :func:`force`), else None (the caller runs its numpy code)."""
    forced = _state["forced"]
    if forced is False:
        return None
    mod = _state["module"]
    if mod is not None:
        return mod
    if forced or (_setting() == "1"):
        return _load()
    return None


def episode_ended() -> None:
    """An env episode ended in this process: the :data:`WARM_EPISODES`-th loads the kernels (unless
    ``PLATE_ENV_JIT=0``)."""
    _state["episodes"] += 1
    if _state["module"] is None and _state["episodes"] >= WARM_EPISODES and _setting() != "0":
        _load()


def force(on: bool | None) -> None:
    """Use the kernels always (True), never (False), or as :func:`kernels` decides (None): for tests comparing the
    two paths."""
    _state["forced"] = on
