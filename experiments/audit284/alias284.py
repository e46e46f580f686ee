"""Map the module paths of HEAD's tests onto main 284a76f's flat layout (audit of issue 28's tests)."""
import importlib
import sys
import types

ALIASES = {
    "plate_env.core.probe_table": "plate_env.probes",
    "plate_env.identify.estimate": "plate_env.estimate",
    "plate_env.identify.forward": "plate_env.forward",
    "plate_env.identify.inference": "plate_env.inference",
    "plate_env.identify.fitting": "plate_env.fitting",
    "plate_env.surrogate.atlas": "plate_env.atlas",
    "plate_env.run.executor": "plate_env.executor",
    "plate_env.run.sweeps": "plate_env.sweeps",
    "plate_env.env.sb3": "plate_env.sb3",
    "plate_env.env.protocol": "plate_env.protocol",
    "plate_env.bench.runner": "plate_env.benchmark",
}
# parents: a flat module at 284a76f (plate_env.identify, plate_env.env) gets an empty __path__ so that
# "plate_env.identify.X" resolves through sys.modules; a parent that did not exist (core, run, bench, ...) is a stub
for pkg in sorted({n.rpartition(".")[0] for n in ALIASES}):
    try:
        m = importlib.import_module(pkg)
    except ImportError:
        m = types.ModuleType(pkg)
        sys.modules[pkg] = m
    if not hasattr(m, "__path__"):
        m.__path__ = []
for new, old in ALIASES.items():
    sys.modules[new] = importlib.import_module(old)
    parent, _, leaf = new.rpartition(".")
    setattr(sys.modules[parent], leaf, sys.modules[new])


# HEAD's executors take map(fn, items) and call fn(item); 284a76f's take map(backend, chunks, task) and call
# task(backend, list(chunk)). The adapter translates the new call onto the old one (items as one-item chunks, a
# picklable task calling fn on the chunk's item), so tests of pool behaviour (items 12, 23) run the old pool code.
import functools  # noqa: E402


def _call_one(fn, backend, chunk):
    return fn(chunk[0])


def _adapt_map(cls):
    old = cls.map

    def map(self, *args, **kw):
        if args and callable(args[0]) and not kw and len(args) == 2:
            fn, items = args
            return old(self, None, [[x] for x in items], task=functools.partial(_call_one, fn))
        return old(self, *args, **kw)

    cls.map = map


_ex = sys.modules["plate_env.run.executor"]
for _name in ("InProcessExecutor", "PoolExecutor"):
    if hasattr(_ex, _name):
        _adapt_map(getattr(_ex, _name))
