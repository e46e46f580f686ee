"""How often a real call path climbs back up the package's layers: one seeded env episode and one ``fit``.

    python experiments/layer_crossings.py [--before DIR]   # DIR: a checkout of the flat layout, e.g.
        # mkdir /tmp/flat && git archive 284a76f | tar -x -C /tmp/flat

Each path runs in a fresh process under ``sys.setprofile``. Every Python call into a module of the project is
mapped to its layer (tests/test_code_health.py ``LAYERS``; a module of the flat layout to the layer its file moved
to, :data:`MOVED_MODULES`) together with the nearest project frame that called it (frames of numpy, gymnasium
and the like are looked through). A *crossing back up* is a call whose callee's layer is above its caller's: a
lower layer calling into a higher one (a callback, a lazy import of an upper module, a function in the wrong
file). Reported: the distinct crossings (caller function -> callee function) and how many calls took them.

The paths: ``gym.make("PlateRotation-v0", physics="atlas")`` (the backend's construction included),
``reset(seed=0)`` and steps drawn from the action space seeded with 0 (never the stop action) until the probe
budget ends the episode and the env estimates; ``plate-env fit sweep.csv`` (the atlas method, the ``lab`` forward
model) on the tile-link sweep of common.SWEEP_CSV. Writes experiments/results/layer_crossings.md.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from common import SWEEP_CSV

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
OUT = HERE / "results" / "layer_crossings.md"
PATHS = ("episode", "fit")
#: The flat layout's module paths (before the layering) -> the module that holds each now, so that a crossing in a
#: commit of the flat layout counts in the layer its file moved to (``"probes:probe_table"``: renamed too).
_MOVED = {"core": ("objects", "motion", "units", "checks", "probes:probe_table", "physics.base:probe"),
          "surrogate": ("atlas",), "physics": ("measure", "camera", "nuisance"),
          "identify": ("fitting", "calibration", "inference", "estimate", "forward"), "run": ("executor", "sweeps"),
          "env": ("vector", "sb3", "render", "episode", "protocol"), "bench": ("suites", "scoring", "reporting"),
          "build": ("atlas_grid", "benchmarks:eval_sets")}
MOVED_MODULES = {f"plate_env.{old}": f"plate_env.{layer}.{new or old}" for layer, names in _MOVED.items()
                 for old, _, new in (n.partition(":") for n in names)}
MOVED_MODULES["plate_env.benchmark"] = "plate_env.bench"
#: The environment variable through which the driver hands MOVED_MODULES to a child that may run the flat layout.
MOVED_VAR = "LAYER_CROSSINGS_MOVED"
IMPORT_SYSTEM = ("importlib._bootstrap", "_frozen_importlib", "importlib._bootstrap_external",
                 "_frozen_importlib_external")


def _health():
    spec = importlib.util.spec_from_file_location("test_code_health", REPO / "tests" / "test_code_health.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def layer_function():
    """module name -> (layer index, layer name) or None, for both layouts."""
    health, moved = _health(), json.loads(os.environ[MOVED_VAR])

    def layer(module: str):
        if not module or not module.startswith(("plate_env", "plate_env_agents")):
            return None
        i = health.layer_of(moved.get(module, module))
        return None if i is None else (i, health.LAYERS[i][0])

    return layer


def trace(which: str) -> dict:
    """Run one path under a profiler; the crossings back up a layer (run in the child process)."""
    layer = layer_function()
    crossings: dict[tuple[str, str], int] = {}
    calls = [0]

    def caller_module(frame):
        f = frame.f_back
        while f is not None:
            name = f.f_globals.get("__name__", "")
            if layer(name) is not None:
                return name, f.f_code.co_name
            f = f.f_back
        return None, None

    def profile(frame, event, arg):
        if event != "call" or frame.f_back is None or frame.f_back.f_globals.get("__name__", "") in IMPORT_SYSTEM:
            return  # the import system asking every finder (plate_env's finder of moved modules) is no call path
        callee = frame.f_globals.get("__name__", "")
        lc = layer(callee)
        if lc is None:
            return
        calls[0] += 1
        caller, fn = caller_module(frame)
        if caller is None or caller == callee:
            return
        lo = layer(caller)
        if lc[0] > lo[0]:
            key = (f"{caller}.{fn} [{lo[1]}]", f"{callee}.{frame.f_code.co_name} [{lc[1]}]")
            crossings[key] = crossings.get(key, 0) + 1

    if which == "episode":
        import gymnasium as gym

        import plate_env  # noqa: F401  (registers the env ids)

        sys.setprofile(profile)
        env = gym.make("PlateRotation-v0", physics="atlas")
        env.action_space.seed(0)
        env.reset(seed=0)
        steps, done = 0, False
        while not done:
            action = env.action_space.sample()
            action[3] = -1.0  # probe, never stop: the episode runs to its probe budget, then estimates
            _, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
            steps += 1
        sys.setprofile(None)
        env.close()
        what = f"{steps} steps"
    else:
        from plate_env.cli import main

        with tempfile.TemporaryDirectory() as tmp:
            csv = Path(tmp) / "sweep.csv"
            csv.write_text(SWEEP_CSV)  # a real tile-link sweep every layout's fit answers (bench_speed's)
            sys.setprofile(profile)
            code = main(["fit", str(csv), "--json"])
            sys.setprofile(None)
        what = f"exit code {code}"
    return {"path": which, "what": what, "calls": calls[0],
            "crossings": [{"from": a, "to": b, "calls": n} for (a, b), n in sorted(crossings.items())]}


def run_child(which: str, tree: Path | None) -> dict:
    env = dict(os.environ, **{MOVED_VAR: json.dumps(MOVED_MODULES)})
    if tree is not None:
        env["PYTHONPATH"] = str(tree) + os.pathsep + env.get("PYTHONPATH", "")
    done = subprocess.run([sys.executable, __file__, "--trace", which], capture_output=True, text=True, env=env,
                          cwd=tempfile.gettempdir())
    if done.returncode != 0:
        raise SystemExit(f"tracing {which} failed:\n{done.stderr[-3000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    layout = "flat" if tree is not None else "layered"
    return {**result, "layout": layout}


def report(results: list[dict]) -> str:
    lines = ["# Layer crossings of two call paths", "",
             "Regenerate: `python experiments/layer_crossings.py --before DIR` (DIR: `git archive 284a76f` of the "
             "flat layout unpacked). How: the module docstring of experiments/layer_crossings.py. A crossing back "
             "up is a call from a module of a lower layer into one of a higher layer (layers: "
             "tests/test_code_health.py `LAYERS`; a flat-layout module counts in the layer its file moved to).", "",
             "| path | layout | project calls traced | distinct crossings back up | calls taking them |",
             "|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r['path']} ({r['what']}) | {r['layout']} | {r['calls']} | {len(r['crossings'])} | "
                     f"{sum(c['calls'] for c in r['crossings'])} |")
    for r in results:
        lines += ["", f"## {r['path']}, {r['layout']} layout", ""]
        if not r["crossings"]:
            lines.append("No call crosses back up a layer.")
            continue
        lines += ["| caller [layer] | callee [layer] | calls |", "|---|---|---|"]
        lines += [f"| `{c['from']}` | `{c['to']}` | {c['calls']} |" for c in r["crossings"]]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trace", choices=PATHS, help=argparse.SUPPRESS)
    ap.add_argument("--before", type=Path, default=None, help="a checkout of the flat layout to count too")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    if args.trace:
        print(json.dumps(trace(args.trace)))
        return
    results = []
    for which in PATHS:
        if args.before is not None:
            results.append(run_child(which, args.before))
        results.append(run_child(which, None))
    text = report(results)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
