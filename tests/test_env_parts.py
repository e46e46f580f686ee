"""The env as parts (issue 35): a frozen, validated EnvConfig; the identification task; one episode state that the
single and the vector env step alike; no reach into another object's private members."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from plate_env.env.config import ARGUMENTS, EnvConfig
from plate_env.env.rotation import PlateRotationEnv
from plate_env.env.vector import PlateRotationVectorEnv

ENV_DIR = Path(__file__).resolve().parents[1] / "plate_env" / "env"


def test_config_is_frozen_checked_once_and_holds_every_argument():
    cfg = EnvConfig(physics="atlas", amplitudes_deg=[3, 12], max_probes=5)
    assert cfg.amplitudes_deg == (3.0, 12.0) and cfg.physics_options == {}  # checked values, not the raw ones
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.max_probes = 6  # type: ignore[misc]
    with pytest.raises(ValueError, match="max_probes"):
        dataclasses.replace(cfg, max_probes=0)  # a changed copy is checked again
    with pytest.raises(TypeError, match="unexpected keyword argument 'max_probe'.*max_probes"):
        PlateRotationEnv(physics="atlas", max_probe=5)
    env = PlateRotationEnv(physics="atlas", max_probes=5)
    assert env.config == EnvConfig(physics="atlas", max_probes=5)
    assert all(getattr(env, name) == getattr(env.config, name) for name in ARGUMENTS if name != "physics")
    with pytest.raises(AttributeError, match="max_probes"):  # a view, read-only: the codec and spaces are built
        env.max_probes = 6
    env.close()


def test_an_env_from_a_config_runs_the_episode_of_its_keywords():
    kwargs = dict(physics="atlas", max_probes=4, amplitudes_deg=(3.0,))
    a, b = PlateRotationEnv(**kwargs), PlateRotationEnv(EnvConfig(**kwargs))
    out = []
    for env in (a, b):
        obs, _ = env.reset(seed=3)
        steps = [env.step(env.encode_action(f, 3.0, 1.0)) for f in (15.0, 20.0, 25.0, 30.0)]
        out.append((obs, [(o.tolist(), r, t) for o, r, t, _, _ in steps], env.estimate().to_dict()))
    assert out[0][1] == out[1][1] and out[0][2] == out[1][2] and np.array_equal(out[0][0], out[1][0])


def test_the_task_charges_the_capped_error_or_the_penalty():
    from plate_env.identify.estimate import Estimate

    env = PlateRotationEnv(physics="atlas", error_cap=0.3, no_estimate_penalty=0.7, cost_per_sim_s=0.01)
    task = env.task
    assert task.probe_cost(2.0) == 0.01 * 2.0
    assert task.charge(Estimate(ok=False, method="atlas", reason="none"), 10.0) == (0.7, None)
    charge, error = task.charge(Estimate(ok=True, method="atlas", omega_n=15.0, omega_n_ci68=(14.0, 16.0),
                                          omega_n_ci95=(13.0, 17.0)), 10.0)
    assert error == pytest.approx(0.5) and charge == 0.3
    assert task.budget_spent(env.max_probes, 0.0) and not task.budget_spent(env.max_probes - 1, 0.0)
    env.close()


def test_the_vector_env_shares_one_backend_it_owns_and_closes_once():
    vec = PlateRotationVectorEnv(num_envs=3, physics="atlas", max_probes=3)
    assert all(env.physics is vec.physics for env in vec.envs)
    vec.envs[0].close()  # a sub-env never closes the shared backend
    vec.envs[1].reset(seed=0)
    vec.envs[1].step(vec.envs[1].encode_action(20.0, 3.0, 1.0))
    closed = []
    vec.physics.close = lambda: closed.append(True)  # type: ignore[method-assign]
    vec.close()
    assert closed == [True]
    with pytest.raises(RuntimeError, match="closed"):
        vec.step(np.zeros((3, 4), np.float32))


def test_the_env_modules_reach_into_no_other_objects_private_members():
    """``obj._name`` only on ``self`` (or ``cls``) in plate_env/env/: the vector env steps the sub-envs' episode
    states through their public methods (at 893bbe6 it called ``env._decode``, set ``env._closed`` and swapped
    ``env.physics``; the SB3 env called ``vec._check_actions``)."""
    found = []
    for path in sorted(ENV_DIR.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                    and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))):
                found.append(f"{path.name}:{node.lineno} .{node.attr}")
    assert found == []
