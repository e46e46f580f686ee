"""PlateRotation-v0 as a Stable-Baselines3 VecEnv (plate_env.sb3): SB3's own semantics, checked against SB3's
DummyVecEnv and with SB3's tools; a short PPO training run; the rl-zoo3 hyperparameter file."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.env_checker import check_env  # noqa: E402
from stable_baselines3.common.evaluation import evaluate_policy  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecCheckNan, VecMonitor  # noqa: E402

from plate_env.env.rotation import PlateRotationEnv  # noqa: E402
from plate_env.env.sb3 import PlateRotationSB3VecEnv, make_sb3_vec_env  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("physics, kw, steps", [("atlas", dict(max_probes=4), 60), ("tilelink", dict(max_probes=3), 8)])
def test_step_for_step_equal_to_sb3s_dummy_vec_env(physics, kw, steps):
    """Same seeds and actions: the same observations, rewards, dones and infos (terminal observations included),
    with autoreset in the step that ends an episode, as SB3's DummyVecEnv does over the single envs."""
    ours = PlateRotationSB3VecEnv(3, physics=physics, **kw)
    ref = DummyVecEnv([lambda: PlateRotationEnv(physics=physics, **kw) for _ in range(3)])
    ours.seed(7)
    ref.seed(7)
    assert np.array_equal(ours.reset(), ref.reset())
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(steps):
        act = rng.uniform(-1, 1, (3, 4)).astype(np.float32)
        act[:, 3] = np.where(rng.random(3) < 0.15, 1.0, -1.0)  # some stops
        (o1, r1, d1, i1), (o2, r2, d2, i2) = ours.step(act), ref.step(act)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and r1.dtype == r2.dtype
        assert np.array_equal(d1, d2)
        for a, b in zip(i1, i2, strict=True):
            assert set(a) == set(b)
            assert a["TimeLimit.truncated"] == b["TimeLimit.truncated"] and a["sim_s"] == b["sim_s"]
            if "terminal_observation" in a:
                assert np.array_equal(a["terminal_observation"], b["terminal_observation"])
                assert a["estimate"] == b["estimate"]
        ended += int(d1.sum())
    assert ended >= 2  # episodes ended and were reset in the step
    ours.close()
    ref.close()


def test_one_batched_physics_call_per_step():
    venv = PlateRotationSB3VecEnv(4, physics="atlas", max_probes=5)
    calls = []
    run = venv.vec.physics.run

    def counting(specs, *a, **k):
        calls.append(len(specs))
        return run(specs, *a, **k)

    venv.vec.physics.run = counting
    venv.seed(0)
    venv.reset()
    for _ in range(3):
        venv.step(np.tile(np.array([0.0, -1.0, 0.0, -1.0], np.float32), (4, 1)))
    assert calls == [4, 4, 4]
    assert all(env.physics is venv.vec.physics for env in venv.envs)


def test_sb3_tools_accept_it():
    check_env(PlateRotationEnv(physics="atlas", max_probes=4), warn=False)  # a sub-environment
    venv = VecCheckNan(make_sb3_vec_env(n_envs=3, physics="atlas", seed=1, max_probes=4), raise_exception=True)
    obs = venv.reset()
    assert venv.observation_space.contains(obs[0]) and obs.shape == (3, 30)
    for _ in range(20):
        obs, rew, done, info = venv.step(np.stack([venv.action_space.sample() for _ in range(3)]))
        assert all(venv.observation_space.contains(o) for o in obs) and np.all(np.isfinite(rew))
    assert venv.get_attr("max_probes") == [4, 4, 4] and venv.env_is_wrapped(VecMonitor) == [False] * 3
    venv.close()


def test_ppo_trains_on_it_and_evaluate_policy_scores_it():
    venv = make_sb3_vec_env(n_envs=4, physics="atlas", seed=0, max_probes=6)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=2, seed=0, device="cpu")
    model.learn(512)
    assert model.num_timesteps >= 512 and len(model.ep_info_buffer) > 0  # VecMonitor reported whole episodes
    mean, std = evaluate_policy(model, make_sb3_vec_env(n_envs=2, physics="atlas", seed=5, max_probes=6),
                                n_eval_episodes=4)
    assert -3.0 < mean <= 0.0 and np.isfinite(std)


def test_vec_env_arguments_are_checked():
    with pytest.raises(ValueError, match="n_envs"):
        PlateRotationSB3VecEnv(0, physics="atlas")
    with pytest.raises(ValueError, match="seed"):
        make_sb3_vec_env(2, seed=-1, physics="atlas")
    with pytest.raises(ValueError, match="max_probes"):
        make_sb3_vec_env(2, physics="atlas", max_probes=0)


#: Keys of an rl-zoo3 hyperparameter entry that rl-zoo3 itself consumes (rl_zoo3/exp_manager.py, 2.x).
RL_ZOO_KEYS = {"n_envs", "n_timesteps", "policy", "policy_kwargs", "env_kwargs", "normalize", "frame_stack",
               "env_wrapper", "vec_env_wrapper", "callback", "monitor_kwargs", "noise_type", "noise_std"}


def test_hyperparameters_are_rl_zoo3_compatible_and_every_env_setting_is_an_env_argument():
    from plate_env_agents import train

    entry = train.load_hyperparams()  # the installed plate_env_agents/hyperparams/ppo.yml
    ppo_args = set(inspect.signature(PPO.__init__).parameters)
    assert set(entry) <= RL_ZOO_KEYS | ppo_args, set(entry) - RL_ZOO_KEYS - ppo_args
    kw = train.env_kwargs_of(entry)
    env = PlateRotationEnv(**kw)  # constructible as gym.make would: no physics swap
    assert env.physics.rho == 0.9 and env.physics.corr_hz == 2.0 and env.max_probes == 30
    env.close()
    assert train.policy_kwargs_of(entry["policy_kwargs"]) == {"net_arch": [64, 64], "log_std_init": -0.5}
    src = (ROOT / "agents" / "train.py").read_text()
    assert "make_sb3_vec_env" in src and not re.search(r"\.physics\s*=", src)  # public API only


def test_the_readme_snippet_is_what_experiments_train_readme_ppo_runs():
    readme = (ROOT / "README.md").read_text()
    script = (ROOT / "experiments" / "train_readme_ppo.py").read_text()
    line = ('model = PPO("MlpPolicy", make_sb3_vec_env(n_envs=8, physics="atlas", seed=0), seed=0, device="cpu", '
            'verbose=1)')
    assert line in readme and line in script
