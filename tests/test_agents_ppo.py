"""The shipped PPO policy (agents/models/ppo_plate.zip) loads without training and probes on the atlas backend."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import plate_env  # noqa: F401 - registers the env

pytest.importorskip("stable_baselines3")

from plate_env.env.episode import run_episode  # noqa: E402
from plate_env.env.protocol import ProbeContext  # noqa: E402
from plate_env_agents import make_agent  # noqa: E402
from plate_env_agents.ppo import DEFAULT_MODEL  # noqa: E402


@pytest.fixture(scope="module")
def agent():
    return make_agent("ppo")


def test_shipped_model_is_small_with_provenance():
    assert DEFAULT_MODEL.exists()
    assert DEFAULT_MODEL.stat().st_size < 1_000_000
    prov = json.loads(DEFAULT_MODEL.with_suffix(".json").read_text())
    for key in ("env_kwargs", "timesteps", "seed", "eval", "date"):
        assert key in prov
    assert prov["env_kwargs"]["physics"] == "atlas"


def test_loads_and_acts_on_env_observation(agent):
    assert agent.name == "ppo" and agent.method == "atlas"
    env = gym.make("PlateRotation-v0", physics="atlas", max_probes=30)
    obs, _ = env.reset(seed=3)
    agent.reset(ProbeContext.from_env(env), np.random.default_rng(3))
    action = agent.next_probe(env.unwrapped.table(), obs)
    assert isinstance(action, np.ndarray) and action.shape == (4,)
    assert np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1.0)
    assert env.action_space.contains(action.astype(np.float32))
    assert action[3] <= 0  # never stops before the first probe
    env.close()


@pytest.mark.parametrize("max_probes", [30, 12])
def test_episode_end_to_end_on_atlas(agent, max_probes):
    env = gym.make("PlateRotation-v0", physics="atlas", max_probes=max_probes)
    res = run_episode(env, agent, seed=11, options={"omega_n": 12 * np.pi, "alpha": np.radians(40)})
    env.close()
    assert 1 <= res.n_probes <= max_probes
    assert res.estimate.ok and res.estimate.method == "atlas"
    assert np.isfinite(res.relative_error) and res.sim_s > 0


def test_deterministic_and_without_observation(agent):
    env = gym.make("PlateRotation-v0", physics="atlas", max_probes=30)
    a = run_episode(env, agent, seed=5)
    b = run_episode(env, agent, seed=5)
    assert np.array_equal(a.probes.f_p_hz, b.probes.f_p_hz) and a.estimate.omega_n == b.estimate.omega_n
    # obs=None: the agent rebuilds the observation from the probe table
    env.reset(seed=5)
    agent.reset(ProbeContext.from_env(env), np.random.default_rng(5))
    action = agent.next_probe(env.unwrapped.table(), None)
    assert action is not None and np.all(np.abs(action) <= 1.0)
    env.close()


def test_missing_model_is_a_clear_error(tmp_path: Path):
    with pytest.raises(FileNotFoundError, match="plate-env build policy"):
        make_agent("ppo", path=tmp_path / "none.zip")


def test_other_band_and_windows_are_translated(agent):
    env = gym.make("PlateRotation-v0", physics="atlas", max_probes=8, f_band_hz=(12.0, 36.0),
                   measure_range_s=(0.5, 3.0))
    res = run_episode(env, agent, seed=2)
    env.close()
    assert 1 <= res.n_probes <= 8 and res.estimate.ok
    assert np.all((res.probes.f_p_hz >= 12.0 - 1e-6) & (res.probes.f_p_hz <= 36.0 + 1e-6))


def test_numpy_forward_pass_equals_sb3_predict(agent, tmp_path: Path):
    """The shipped agent acts from the numpy export; its actions are SB3's predict to float32 rounding, and an
    export of another model file (a stale one) is not used."""
    import shutil

    from stable_baselines3 import PPO

    assert agent.backend == "numpy"
    model = PPO.load(DEFAULT_MODEL, device="cpu")
    rng = np.random.default_rng(0)
    env = gym.make("PlateRotation-v0", physics="atlas")
    obs = [env.reset(seed=s)[0] for s in range(3)] + list(rng.uniform(-1, 1, (200, agent.obs_dim)).astype(np.float32))
    env.close()
    for o in obs:
        ref = np.clip(model.predict(o, deterministic=True)[0], -1, 1)
        assert np.max(np.abs(agent.act(o) - ref)) < 1e-5
    copy = tmp_path / "ppo.zip"
    shutil.copyfile(DEFAULT_MODEL, copy)
    shutil.copyfile(DEFAULT_MODEL.with_suffix(".npz"), copy.with_suffix(".npz"))
    with open(copy, "ab") as fh:
        fh.write(b"\0")  # another file: the export's hash no longer matches
    assert make_agent("ppo", path=copy).backend == "sb3"
