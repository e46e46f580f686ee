"""Packaging: the agents install under the project's namespace (``plate_env_agents``, from the folder agents/), the
package list is complete, heavy imports stay lazy."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python 3.11+
ROOT = Path(__file__).resolve().parents[1]


def test_the_package_list_names_every_package():
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "plate_env").rglob("__init__.py")}
    assert set(cfg["packages"]) == found | {"plate_env_agents"}
    assert cfg["package-dir"] == {"plate_env_agents": "agents"}


def test_nothing_imports_the_generic_name_agents():
    bad = []
    for folder in ("plate_env", "agents", "experiments", "tests", "examples"):
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                    [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
                bad += [f"{path.relative_to(ROOT)}: {n}" for n in names if n.split(".")[0] == "agents"]
    assert bad == []


def test_installed_names_and_lazy_heavy_imports(tmp_path):
    """Outside the source tree: plate_env_agents imports, ``agents`` does not exist, and the shipped PPO policy
    acts without importing torch or Stable-Baselines3 (its numpy export)."""
    code = ("import importlib.util, sys, numpy as np\n"
            "import plate_env_agents\n"
            "assert importlib.util.find_spec('agents') is None\n"
            "a = plate_env_agents.make_agent('ppo')\n"
            "from plate_env.env import PlateRotationEnv\n"
            "from plate_env.env.protocol import ProbeContext\n"
            "env = PlateRotationEnv(physics='atlas')\n"
            "obs, _ = env.reset(seed=0)\n"
            "a.reset(ProbeContext.from_env(env), np.random.default_rng(0))\n"
            "act = a.next_probe(env.unwrapped.table(), obs)\n"
            "print(a.backend, 'torch' in sys.modules, 'stable_baselines3' in sys.modules, act.shape)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["numpy", "False", "False", "(4,)"]


@pytest.mark.slow
def test_a_regular_wheel_holds_the_agents_under_their_namespace(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True)
    (wheel,) = tmp_path.glob("plate_env-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "plate_env_agents/models/ppo_plate.zip" in names and "plate_env_agents/models/ppo_plate.npz" in names
    assert "plate_env_agents/hyperparams/ppo.yml" in names  # what plate-env build policy trains from
    assert "plate_env_agents/models/bayes_design_discrepancy.json" in names
    assert "plate_env/data/suites/tilelink-v0.json" in names and "plate_env/data/forward_models.json" in names
    assert not any(n.startswith("agents/") for n in names)
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target), str(wheel)],
                   check=True)
    code = ("import importlib.util, plate_env_agents\n"
            "from plate_env.bench import evaluate\n"
            "assert importlib.util.find_spec('agents') is None\n"
            "from plate_env_agents.train import hyperparams_file\n"
            "run = evaluate(plate_env_agents.load_agent('ppo'), 'atlas-v0', limit=1)\n"
            f"print(plate_env_agents.__file__.startswith({str(target)!r}), "
            f"str(hyperparams_file()).startswith({str(target)!r}), "
            "plate_env_agents.load_agent('ppo').backend)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(target)})
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "numpy"]  # the installed copy, its package data, no source tree


def test_the_old_benchmark_path_fails_naming_the_new_one():
    """``from plate_env.benchmark import evaluate`` (the README's path before the layers) fails with a message that
    names plate_env.bench; the other flat paths, never released, are plain ImportErrors; no import hook is left in
    sys.meta_path (issue 35)."""
    code = ("import sys, plate_env\n"
            "print(sorted(type(f).__module__ for f in sys.meta_path if type(f).__module__.startswith('plate_env')))\n"
            "try:\n"
            "    from plate_env.benchmark import evaluate\n"
            "except ImportError as e:\n"
            "    print('refused:', e)\n"
            "from plate_env.bench import evaluate\n"
            "try:\n"
            "    import plate_env.objects\n"
            "except ModuleNotFoundError:\n"
            "    print('missing')\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "[]" and lines[2] == "missing"
    assert lines[1].startswith("refused: plate_env.benchmark moved to plate_env.bench")
