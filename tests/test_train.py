"""``plate-env build policy``: trains from the hyperparameters installed with the package, records how, and is
deterministic for a seed on one machine and torch build (two trainings in one process, one torch thread)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

from plate_env.cli import main  # noqa: E402
from plate_env_agents.train import hyperparams_file, load_hyperparams  # noqa: E402

#: A tiny variant of the installed entry: 2 envs x 64 steps, 256 steps in all (a few seconds).
TINY = {"n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 2, "n_timesteps": 256}


@pytest.fixture(scope="module")
def tiny_file(tmp_path_factory):
    table = yaml.safe_load(hyperparams_file("ppo").read_text())
    table["PlateRotation-v0"].update(TINY)
    path = tmp_path_factory.mktemp("hp") / "tiny.yml"
    path.write_text(yaml.safe_dump(table))
    return path


def _params(zip_path) -> dict[str, np.ndarray]:
    from stable_baselines3 import PPO

    return {k: v.detach().numpy().copy() for k, v in PPO.load(zip_path, device="cpu").policy.state_dict().items()}


def _train(tmp_path, name: str, tiny_file, seed: int) -> tuple[dict, dict]:
    out = tmp_path / f"{name}.zip"
    argv = ["policy", "--out", str(out), "--hyperparams", str(tiny_file), "--eval-freq", "0", "--seed", str(seed)]
    assert main(["build", *argv]) == 0
    return _params(out), json.loads(out.with_suffix(".json").read_text()) | {"argv": argv}


def test_a_tiny_policy_trained_twice_with_one_seed_has_identical_parameters_and_records_how(tmp_path, tiny_file):
    a, meta = _train(tmp_path, "a", tiny_file, seed=3)
    b, _ = _train(tmp_path, "b", tiny_file, seed=3)
    c, _ = _train(tmp_path, "c", tiny_file, seed=4)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)  # bit for bit
    assert any(not np.array_equal(a[k], c[k]) for k in a)  # another seed, another policy: the check can fail
    from plate_env.identify.lab_calibration_file import package_version

    build = meta["build"]
    assert build["command"] == "plate-env build " + " ".join(meta["argv"]) == meta["command"]
    assert build["plate_env"] == package_version() != "unknown"
    assert build["commit"] is None or len(build["commit"].removesuffix("+dirty")) == 40
    assert meta["seed"] == 3 and meta["timesteps"] == 256 and meta["torch_threads"] == 1
    assert meta["hyperparams"] == load_hyperparams(tiny_file) and meta["versions"]["torch"]
    assert (tmp_path / "a.npz").is_file()  # the numpy export make_agent("ppo") acts from


def test_build_policy_trains_from_the_installed_hyperparameters(tmp_path):
    out = tmp_path / "p.zip"
    assert main(["build", "policy", "--out", str(out), "--timesteps", "1", "--eval-freq", "0"]) == 0
    meta = json.loads(out.with_suffix(".json").read_text())
    installed = yaml.safe_load(hyperparams_file("ppo").read_text())["PlateRotation-v0"]
    assert meta["hyperparams"] == installed and meta["hyperparams_file"].startswith("plate_env_agents/hyperparams/")
    assert meta["timesteps"] == installed["n_envs"] * installed["n_steps"]  # SB3 finishes the rollout it is in
    from plate_env_agents.zoo import hyperparams  # what rl-zoo3's --conf-file plate_env_agents.zoo reads

    assert hyperparams["PlateRotation-v0"] == installed


def test_the_hyperparameter_file_is_found_from_the_installed_package(tmp_path):
    """Outside the source tree, through importlib.resources: the file ``build policy`` reads by default."""
    code = ("import importlib.resources as r\n"
            "from plate_env_agents.train import hyperparams_file\n"
            "p = r.files('plate_env_agents') / 'hyperparams' / 'ppo.yml'\n"
            "print(p.is_file(), str(hyperparams_file('ppo')) == str(p), 'PlateRotation-v0:' in p.read_text())\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "True"]


def test_build_policy_refuses_bad_arguments_before_training(tmp_path, capsys):
    out = tmp_path / "p.zip"
    assert main(["build", "policy", "--out", str(out), "--timesteps", "0"]) == 2
    assert "--timesteps 0" in capsys.readouterr().err
    assert main(["build", "policy", "--out", str(tmp_path / "no" / "p.zip")]) == 2
    assert "does not exist" in capsys.readouterr().err
    (tmp_path / "bad.yml").write_text("PlateRotation-v0:\n  normalize: true\n")
    assert main(["build", "policy", "--out", str(out), "--hyperparams", str(tmp_path / "bad.yml")]) == 2
    assert "normalize" in capsys.readouterr().err and not out.exists()
    with pytest.raises(ValueError, match="no hyperparameters for 'ddpg'"):
        hyperparams_file("ddpg")  # td3 has a file now (issue 41 item 3)
