"""A vector ``PlateRotation-v0`` whose probes run as one batched physics call (``gymnasium.make_vec`` with
``vectorization_mode="vector_entry_point"``). Same numbers as N single envs (tile-link batches are bit-identical
to single runs); autoreset follows Gymnasium's default NEXT_STEP mode."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

from plate_env.core import checks
from plate_env.env.config import EnvConfig, build_physics
from plate_env.env.rotation import PlateRotationEnv
from plate_env.env.state import Step, step_episodes


class PlateRotationVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """``num_envs`` environments sharing one physics backend; each step's probes run in one batched call.
    ``max_episode_steps`` (the registered spec's, passed by ``gymnasium.make_vec``) truncates a sub-environment's
    episode after that many steps, as ``gymnasium.make``'s TimeLimit does; None: the env's own ending only."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"]}

    def __init__(self, num_envs: int = 2, max_episode_steps: int | None = None, **kwargs: Any) -> None:
        num_envs = checks.integer("num_envs", num_envs, 1, 10_000)
        if max_episode_steps is not None:
            max_episode_steps = checks.integer("max_episode_steps", max_episode_steps, 1, 10**9)
        self.max_episode_steps = max_episode_steps
        self._elapsed = np.zeros(num_envs, dtype=np.int64)
        config = EnvConfig.of(kwargs)
        #: The one backend the sub-environments share (this env owns it: it closes it).
        self.physics = build_physics(config)
        try:
            self.envs = [PlateRotationEnv(config, shared_physics=self.physics) for _ in range(num_envs)]
        except ValueError:  # the backend cannot answer the probes the settings allow
            self.physics.close()
            raise
        self.num_envs = num_envs
        self.render_mode = config.render_mode
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._autoreset = np.zeros(num_envs, dtype=bool)
        self._obs = _array(create_empty_array(self.single_observation_space, num_envs, fn=np.zeros))
        self._closed = False

    def reset(self, *, seed: int | np.integer | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds for {self.num_envs} environments")
        infos: dict[str, Any] = {}
        obs: list[np.ndarray] = []
        for i, (env, s) in enumerate(zip(self.envs, seeds, strict=True)):
            o, info = env.reset(seed=s, options=options)
            obs.append(o)
            infos = self._add_info(infos, info, i)
        self._autoreset[:] = False
        self._elapsed[:] = 0
        self._obs = _array(concatenate(self.single_observation_space, obs, self._obs))
        return self._obs.copy(), infos

    def step(self, actions: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        actions = self.check_actions(actions)
        outcomes = self.step_envs(actions, ~self._autoreset)
        obs: list[np.ndarray] = []
        infos: dict[str, Any] = {}
        rewards = np.zeros(self.num_envs)
        terms = np.zeros(self.num_envs, dtype=bool)
        truncs = np.zeros(self.num_envs, dtype=bool)
        for i, (env, out) in enumerate(zip(self.envs, outcomes, strict=True)):
            if out is None:  # NEXT_STEP autoreset: this env ended on the previous step
                o, info = env.reset()
                self._elapsed[i] = 0
            else:
                o, rewards[i], terms[i], truncs[i], info = out
                self._elapsed[i] += 1
                if self.max_episode_steps is not None and self._elapsed[i] >= self.max_episode_steps:
                    truncs[i] = True
            obs.append(o)
            infos = self._add_info(infos, info, i)
        self._autoreset = terms | truncs
        self._obs = _array(concatenate(self.single_observation_space, obs, self._obs))
        return self._obs.copy(), rewards, terms, truncs, infos

    def check_actions(self, actions: npt.ArrayLike) -> np.ndarray:
        """The batch of actions as an array of the action space's shape, or ValueError (each action is checked by
        its sub-environment's episode when it steps)."""
        actions = np.asarray(actions)
        if actions.shape != self.action_space.shape:
            raise ValueError(f"actions must have shape {self.action_space.shape}, got {actions.shape}")
        return actions

    def step_envs(self, actions: np.ndarray, active: np.ndarray) -> list[Step | None]:
        """Step the sub-environments where ``active`` is True, their probes in one batched physics call: per
        sub-environment ``(obs, reward, terminated, truncated, info)``, or None where inactive. (The step of this
        vector env and of :class:`plate_env.env.sb3.PlateRotationSB3VecEnv`; they differ in how they reset.)"""
        if self._closed:
            raise RuntimeError("this PlateRotationVectorEnv is closed; make a new one")
        # the one step of every form of the env: every action checked before any draws (a clean rerun matches),
        # the probes in one batched call of the shared backend
        return step_episodes(self.physics, [(env.episode, env.np_random, actions[i]) if active[i] else None
                                            for i, env in enumerate(self.envs)])

    # gymnasium's VectorEnv.render declares tuple[RenderFrame, ...] | None, narrower than what its own
    # SyncVectorEnv.render returns (each sub-environment's render(): a list of frames in rgb_array_list, None
    # without a render_mode), which this returns too
    def render(self) -> tuple[np.ndarray | list[np.ndarray] | None, ...]:  # type: ignore[override]
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs: Any) -> None:
        if not self._closed:
            self._closed = True
            for env in self.envs:
                env.close()  # its renderer; the shared backend is this env's to close
            self.physics.close()


def _array(batch: object) -> np.ndarray:
    """``batch`` (gymnasium's ``create_empty_array`` or ``concatenate`` of the env's Box observation space, typed
    as any space's batch) as the array it is."""
    assert isinstance(batch, np.ndarray), type(batch)  # a Box space batches into one array
    return batch
