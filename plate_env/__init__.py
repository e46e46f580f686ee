"""plate-env: read a thin deformable object's bending stiffness from how fast it turns on a vibrating plate.

Light to import: numba, pybullet, matplotlib and torch load only when the code that needs them runs.

The package is layered, each layer importing only the ones below it: :mod:`plate_env.core` ->
:mod:`plate_env.surrogate` -> :mod:`plate_env.physics` -> :mod:`plate_env.identify` -> :mod:`plate_env.run` ->
:mod:`plate_env.env` -> :mod:`plate_env.bench` -> :mod:`plate_env.build`, with the command line and plots at the
edge.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import warnings

from plate_env.core.motion import PlateMotion
from plate_env.core.objects import PRESETS, ObjectSpec, preset
from plate_env.env.ids import ENV_IDS, FAITHFUL_IDS, register
from plate_env.physics import PHYSICS_NAMES, ProbeResult, ProbeSpec, make_physics

__version__ = "0.1.0"

#: The flat layout's module paths, which still import (with a DeprecationWarning naming the new path): old path ->
#: the module that now holds it (``plate_env.physics.base``'s ``Physics`` protocol is in
#: ``plate_env.physics.interface``). The project's own code imports the new paths (tests/test_code_health.py).
#: Old name -> new module, grouped by layer (``"probes:probe_table"``: the module was renamed too).
_MOVED = {"core": ("objects", "motion", "units", "checks", "probes:probe_table", "physics.base:probe"),
          "surrogate": ("atlas",), "physics": ("measure", "camera", "nuisance"),
          "identify": ("fitting", "calibration", "inference", "estimate", "forward"), "run": ("executor", "sweeps"),
          "env": ("vector", "sb3", "render", "episode", "protocol"), "bench": ("suites", "scoring", "reporting"),
          "build": ("atlas_grid", "benchmarks:eval_sets")}
MOVED_MODULES = {f"plate_env.{old}": f"plate_env.{layer}.{new or old}" for layer, names in _MOVED.items()
                 for old, _, new in (n.partition(":") for n in names)}
MOVED_MODULES["plate_env.benchmark"] = "plate_env.bench"


class _MovedModuleFinder:
    """Imports an old module path (:data:`MOVED_MODULES`) as its new module, with a DeprecationWarning naming it (a
    meta path finder and loader, :pep:`451`)."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in MOVED_MODULES:
            return None
        from importlib.machinery import ModuleSpec

        return ModuleSpec(fullname, self)

    def create_module(self, spec):
        new = MOVED_MODULES[spec.name]
        warnings.warn(f"{spec.name} moved to {new}: import {new} instead", DeprecationWarning, stacklevel=2)
        module = importlib.import_module(new)
        self._spec = module.__spec__
        return module

    def exec_module(self, module) -> None:
        module.__spec__ = self._spec  # the import system set the old name's spec on the new module: restore it


class _RegisterWhenGymnasiumLoads:
    """Registers the env ids (:func:`~plate_env.env.ids.register`) as soon as gymnasium is imported, so that
    ``import plate_env`` does not import gymnasium (0.1-0.3 s the command line's fit, probe and sweep do not need)
    and ``gym.make`` still finds them: a meta path finder that, for ``gymnasium`` only, returns the spec the other
    finders give with a loader that runs gymnasium's own and then registers. It stays in place until gymnasium is
    actually executed, so a library that only asks whether gymnasium exists (``importlib.util.find_spec``, as
    torchrl does) before importing it does not use it up (issue 41)."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "gymnasium":
            return None
        for finder in list(sys.meta_path):
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(fullname, path, target)
            if spec is not None:
                if spec.loader is not None:
                    spec.loader = _RegisteringLoader(spec.loader)
                return spec
        return None


class _RegisteringLoader:
    """gymnasium's loader, then :func:`~plate_env.env.ids.register` (every other attribute is the wrapped loader's)."""

    def __init__(self, loader) -> None:
        self._loader = loader

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module) -> None:
        self._loader.exec_module(module)
        register()
        for finder in [f for f in sys.meta_path if isinstance(f, _RegisterWhenGymnasiumLoads)]:
            sys.meta_path.remove(finder)

    def __getattr__(self, name: str):
        return getattr(self._loader, name)


def __getattr__(name: str):
    """``plate_env.objects`` and the other old submodule attributes: the moved module, with a DeprecationWarning."""
    if f"plate_env.{name}" in MOVED_MODULES:
        return importlib.import_module(f"plate_env.{name}")
    raise AttributeError(f"module 'plate_env' has no attribute {name!r}")


if not any(isinstance(f, _MovedModuleFinder) for f in sys.meta_path):
    sys.meta_path.append(_MovedModuleFinder())
if "gymnasium" in sys.modules:
    register()
elif not any(isinstance(f, _RegisterWhenGymnasiumLoads) for f in sys.meta_path):
    sys.meta_path.insert(0, _RegisterWhenGymnasiumLoads())

__all__ = ["ENV_IDS", "FAITHFUL_IDS", "PHYSICS_NAMES", "PRESETS", "ObjectSpec", "PlateMotion", "ProbeResult",
           "ProbeSpec", "__version__", "make_physics", "preset"]
