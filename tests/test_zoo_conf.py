"""rl-zoo3's ``--conf-file plate_env_agents.zoo`` serves the entries of the ``--algo`` on the command line, each of
which the algorithm's constructor takes (issue 41 item 3: SAC got PPO's n_epochs), and refuses the others."""

from __future__ import annotations

import importlib
import inspect

import gymnasium as gym
import pytest

import plate_env  # noqa: F401 - registers the ids

sb3 = pytest.importorskip("stable_baselines3")
pytest.importorskip("yaml")

from plate_env_agents import zoo  # noqa: E402

#: Keys of an rl-zoo3 entry that rl-zoo3 itself consumes (rl_zoo3/exp_manager.py, 2.x); the rest go to the algorithm.
RL_ZOO_KEYS = {"n_envs", "n_timesteps", "policy", "policy_kwargs", "env_kwargs", "normalize", "frame_stack",
               "env_wrapper", "vec_env_wrapper", "callback", "monitor_kwargs", "noise_type", "noise_std"}


@pytest.mark.parametrize("algo", zoo.ZOO_ALGOS)
def test_each_algorithm_s_entries_build_that_algorithm(algo):
    table = zoo.hyperparams_of(algo)
    assert {"PlateRotation-v0", "PlateRotationAtlas-v0"} <= set(table)
    cls = getattr(sb3, algo.upper())
    for env_id, entry in table.items():
        rest = {k: v for k, v in entry.items() if k not in RL_ZOO_KEYS}
        assert set(rest) <= set(inspect.signature(cls.__init__).parameters), (algo, env_id, set(rest))
        env = gym.make(env_id, **entry.get("env_kwargs", {}))
        cls(entry["policy"], env, device="cpu", **rest)  # rl-zoo3 passes these keys as is (PPO's n_epochs to SAC
        env.close()                                       # raised TypeError)


def test_the_module_serves_the_algo_on_the_command_line_and_refuses_others(monkeypatch):
    assert zoo.algo_from_argv(["train.py", "--env", "X", "--algo", "SAC"]) == "sac"
    assert zoo.algo_from_argv(["train.py", "--algo=td3"]) == "td3" and zoo.algo_from_argv(["train.py"]) == "ppo"
    monkeypatch.setattr("sys.argv", ["rl_zoo3.train", "--algo", "sac", "--conf-file", "plate_env_agents.zoo"])
    try:
        assert importlib.reload(zoo).hyperparams == zoo.hyperparams_of("sac") != zoo.hyperparams_of("ppo")
        monkeypatch.setattr("sys.argv", ["rl_zoo3.train", "--algo", "dqn"])
        with pytest.raises(ValueError, match="--algo dqn: plate_env_agents.zoo ships rl-zoo3 entries for ppo, sac, "
                                             "td3, a2c only"):
            importlib.reload(zoo)
    finally:
        monkeypatch.undo()
        importlib.reload(zoo)
    assert zoo.hyperparams == zoo.hyperparams_of("ppo")
