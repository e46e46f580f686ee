"""PlateRotation-v0 as a Stable-Baselines3 ``VecEnv``: one batched physics call per step for all sub-environments.

    from stable_baselines3 import PPO
    from plate_env.env.sb3 import make_sb3_vec_env

    model = PPO("MlpPolicy", make_sb3_vec_env(n_envs=8, physics="atlas", seed=0), seed=0)
    model.learn(100_000)

:class:`PlateRotationSB3VecEnv` follows SB3's conventions, exactly those of its ``DummyVecEnv`` over the same
environments (tests/test_sb3.py compares them step by step): a sub-environment whose episode ends is reset in the
same step, its last observation goes to ``infos[i]["terminal_observation"]`` and the returned observation is the new
episode's first; ``infos[i]["TimeLimit.truncated"]`` says a truncation; ``seed(s)`` seeds the next reset with
``s + i``; rewards are float32. The probes of all sub-environments run as one call of the shared backend (the
tile-link kernels batch them, bit-identical to single runs). Imports Stable-Baselines3: import this module only
to train with it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecMonitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from plate_env.core import checks
from plate_env.env.vector import PlateRotationVectorEnv


class PlateRotationSB3VecEnv(VecEnv):
    """``n_envs`` PlateRotation-v0 environments with the keyword arguments ``env_kwargs`` (one physics backend)."""

    def __init__(self, n_envs: int = 8, **env_kwargs: Any) -> None:
        n_envs = checks.integer("n_envs", n_envs, 1, 10_000)
        self.vec = PlateRotationVectorEnv(num_envs=n_envs, **env_kwargs)
        # the bare PlateRotationEnv sub-environments (their class not typed while it is refactored, issue 35)
        self.envs: list[Any] = self.vec.envs
        super().__init__(n_envs, self.vec.single_observation_space, self.vec.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        obs = []
        for i, env in enumerate(self.envs):
            options = {"options": self._options[i]} if self._options[i] else {}
            o, self.reset_infos[i] = env.reset(seed=self._seeds[i], **options)
            obs.append(o)
        self._reset_seeds()
        self._reset_options()
        return np.stack(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = self.vec.check_actions(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        outcomes = self.vec.step_envs(self._actions, np.ones(self.num_envs, dtype=bool))
        self._actions = None
        obs = []
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos: list[dict[str, Any]] = []
        for i, (env, outcome) in enumerate(zip(self.envs, outcomes, strict=True)):
            assert outcome is not None  # every sub-environment stepped (all active)
            o, r, terminated, truncated, info = outcome
            rewards[i] = r
            dones[i] = terminated or truncated
            info["TimeLimit.truncated"] = truncated and not terminated
            if dones[i]:
                info["terminal_observation"] = o
                o, self.reset_infos[i] = env.reset()
            obs.append(o)
            infos.append(info)
        return np.stack(obs), rewards, dones, infos

    def close(self) -> None:
        self.vec.close()

    def _indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.envs[i], attr_name) for i in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for i in self._indices(indices):
            setattr(self.envs[i], attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        return [getattr(self.envs[i], method_name)(*method_args, **method_kwargs) for i in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper[Any, Any, Any, Any]],
                       indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._indices(indices)]  # the sub-environments are bare PlateRotationEnv

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [env.render() for env in self.envs]


def make_sb3_vec_env(n_envs: int = 8, seed: int | None = None, monitor: bool = True, **env_kwargs: Any) -> VecEnv:
    """The SB3 vector env of ``n_envs`` PlateRotation-v0 environments (``env_kwargs``: the env's arguments, e.g.
    ``physics="atlas"``), seeded with ``seed + i`` at the first reset, and by default wrapped in ``VecMonitor`` (the
    episode returns and lengths SB3 logs)."""
    venv: VecEnv = PlateRotationSB3VecEnv(n_envs, **env_kwargs)
    if seed is not None:
        venv.seed(checks.integer("seed", seed, 0, 2 ** 63 - 1))
    return VecMonitor(venv) if monitor else venv


__all__ = ["PlateRotationSB3VecEnv", "make_sb3_vec_env"]
