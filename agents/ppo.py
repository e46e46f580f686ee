"""A trained Stable-Baselines3 PPO probing policy (experiments/train_rl.py), acting from the env observation.

The shipped model, ``agents/models/ppo_plate.zip``, was trained on ``PlateRotation-v0`` with ``physics="atlas"``
(probes answered from the tile-link response atlas in microseconds) and the settings the CLI's ``identify`` uses:
max_probes 30, plate amplitudes 3 and 12 deg, band 10-40 Hz, windows 0.25-2 s. Its provenance (env kwargs,
timesteps, seed, evaluation reward, date) is in ``ppo_plate.json`` next to it. The estimate is the atlas
posterior (``method = "atlas"``), the estimator the policy was rewarded with.

``next_probe`` returns the raw action of ``model.predict(obs, deterministic=True)`` (f_p, amplitude, window and
stop, each in [-1, 1]; agents.runner passes it to the env as is), or None when the stop component is positive.

Other budgets. The observation has one 7-feature row per probe slot, so its length depends on ``max_probes``.
An observation of another length is re-laid out to the model's: the filled rows are copied (up to the model's
slot count), the probes-left fraction is recomputed against the model's slot count and the sim-seconds-left
fraction is passed through. Once the model's slots are full the agent stops. Without an observation (``obs``
None) the agent rebuilds one from the probe table and the windows it chose itself.

Other band, amplitudes or windows. The model's actions and observation rows are in its training coordinates
(``ppo_plate.json`` env_kwargs); when the env's differ, the agent translates both ways through physical units
(Hz, deg, s), clipping to the env's ranges and taking the nearest amplitude (a warning names amplitudes the
policy never saw). With the training settings (the CLI's defaults) the action is the model's, untouched.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from agents.base import Agent, ProbeContext
from plate_env.env import N_FEATURES
from plate_env.probes import ProbeTable

#: The model shipped with the package.
DEFAULT_MODEL = Path(__file__).parent / "models" / "ppo_plate.zip"


class PPOAgent(Agent):
    """Probing by a trained PPO policy; ``path`` is its SB3 zip (default: the shipped model)."""

    name = "ppo"
    method = "atlas"

    def __init__(self, path: str | Path | None = None, deterministic: bool = True, device: str = "cpu") -> None:
        from stable_baselines3 import PPO

        self.path = Path(path) if path is not None else DEFAULT_MODEL
        if not self.path.exists():
            raise FileNotFoundError(f"no PPO model at {self.path}; train one with experiments/train_rl.py")
        self.model = PPO.load(self.path, device=device)
        self.deterministic = deterministic
        self.obs_dim = int(self.model.observation_space.shape[0])
        self.n_slots = (self.obs_dim - 2) // N_FEATURES
        meta = self.path.with_suffix(".json")
        self.provenance = json.loads(meta.read_text()) if meta.exists() else {}
        env_kwargs = self.provenance.get("env_kwargs", {})
        self.method = env_kwargs.get("method", "atlas")
        self.trained_band = tuple(env_kwargs.get("f_band_hz", (10.0, 40.0)))
        self.trained_amps = tuple(env_kwargs.get("amplitudes_deg", (3.0, 12.0)))
        self.trained_windows = tuple(env_kwargs.get("measure_range_s", (0.25, 2.0)))
        self._windows: list[float] = []

    def reset(self, context: ProbeContext, rng: np.random.Generator) -> None:
        super().reset(context, rng)
        self._windows = []
        self._same = (np.allclose(context.f_band_hz, self.trained_band)
                      and len(context.amplitudes_deg) == len(self.trained_amps)
                      and np.allclose(context.amplitudes_deg, self.trained_amps)
                      and np.allclose(context.measure_range_s, self.trained_windows))
        foreign = [a for a in context.amplitudes_deg if not np.any(np.isclose(self.trained_amps, a))]
        if foreign:
            warnings.warn(f"PPO policy trained on amplitudes {self.trained_amps} deg, the env offers {foreign}: "
                          "its amplitude choices are mapped to the nearest one", stacklevel=2)

    # ----------------------------------------------------------------- translation env <-> model
    @staticmethod
    def _unit(x, lo: float, hi: float):
        """Physical value -> the env's [-1, 1] coordinate over (lo, hi)."""
        return 2 * (np.asarray(x, dtype=np.float64) - lo) / (hi - lo) - 1

    @staticmethod
    def _phys(u, lo: float, hi: float):
        """The env's [-1, 1] coordinate over (lo, hi) -> physical value."""
        return lo + (np.asarray(u, dtype=np.float64) + 1) / 2 * (hi - lo)

    @staticmethod
    def _amp_code(k: int, n: int) -> float:
        return (2 * k + 1) / n - 1 if n > 1 else 0.0

    def _rows_to_model(self, obs: np.ndarray, n: int) -> np.ndarray:
        """Re-express the first ``n`` observation rows from the env's band/amplitudes/windows in the model's."""
        if self._same or n == 0:
            return obs
        ctx = self.context
        rows = obs[: N_FEATURES * n].reshape(n, N_FEATURES).astype(np.float64)
        env_amps, amps = np.asarray(ctx.amplitudes_deg), np.asarray(self.trained_amps)
        f = self._phys(rows[:, 0], *ctx.f_band_hz)
        k_env = np.clip(np.floor((rows[:, 1] + 1) / 2 * len(env_amps)), 0, len(env_amps) - 1).astype(int)
        k = np.array([int(np.argmin(np.abs(amps - env_amps[i]))) for i in k_env])
        win = self._phys(rows[:, 5], *ctx.measure_range_s)
        rows[:, 0] = self._unit(f, *self.trained_band)
        rows[:, 1] = [self._amp_code(i, len(amps)) for i in k]
        rows[:, 5] = self._unit(win, *self.trained_windows)
        out = obs.copy()
        out[: N_FEATURES * n] = np.clip(rows, -10, 10).ravel()
        return out

    def _action_to_env(self, action: np.ndarray) -> np.ndarray:
        """The model's action (over its training band/amplitudes/windows) as the env's action."""
        if self._same:
            return action
        ctx = self.context
        amps = self.trained_amps
        f = float(np.clip(self._phys(action[0], *self.trained_band), *ctx.f_band_hz))
        a_p = amps[min(int((action[1] + 1) / 2 * len(amps)), len(amps) - 1)]
        k = int(np.argmin(np.abs(np.asarray(ctx.amplitudes_deg) - a_p)))
        win = float(np.clip(self._phys(action[2], *self.trained_windows), *ctx.measure_range_s))
        out = np.array([self._unit(f, *ctx.f_band_hz), self._amp_code(k, len(ctx.amplitudes_deg)),
                        self._unit(win, *ctx.measure_range_s), action[3]], dtype=np.float32)
        return np.clip(out, -1.0, 1.0)

    # ----------------------------------------------------------------- observation
    def _from_history(self, history: ProbeTable) -> np.ndarray:
        """The model's observation rebuilt from the probe table (windows: the ones this agent chose, else 1 s)."""
        obs = np.zeros(self.obs_dim, dtype=np.float32)
        amps = np.asarray(self.trained_amps)
        n = min(len(history), self.n_slots)
        for i in range(n):
            k = int(np.argmin(np.abs(amps - history.a_p_deg[i])))
            win = self._windows[i] if i < len(self._windows) else 1.0
            obs[N_FEATURES * i: N_FEATURES * (i + 1)] = (
                self._unit(history.f_p_hz[i], *self.trained_band), self._amp_code(k, len(amps)),
                np.clip(history.omega_b_deg_s[i] / 1000.0, -10, 10), np.clip(history.stderr_deg_s[i] / 1000.0, 0, 10),
                float(history.unstable[i]), self._unit(win, *self.trained_windows), 1.0)
        obs[-2] = max(1.0 - len(history) / self.n_slots, 0.0)
        obs[-1] = 1.0  # the simulated-seconds budget is not in the table: unlimited, as in training
        return np.clip(obs, -10.0, 10.0)

    def adapt(self, obs: np.ndarray, n_probes: int) -> np.ndarray:
        """An env observation laid out for the model (see the module docstring for other budgets)."""
        obs = np.asarray(obs, dtype=np.float32).ravel()
        if obs.shape[0] == self.obs_dim:
            return obs
        if (obs.shape[0] - 2) % N_FEATURES:
            raise ValueError(f"observation of length {obs.shape[0]} is not a PlateRotation-v0 observation")
        out = np.zeros(self.obs_dim, dtype=np.float32)
        n = min(n_probes, self.n_slots, (obs.shape[0] - 2) // N_FEATURES)
        out[: N_FEATURES * n] = obs[: N_FEATURES * n]
        out[-2] = max(1.0 - n_probes / self.n_slots, 0.0)
        out[-1] = obs[-1]
        return out

    # ----------------------------------------------------------------- policy
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The policy's action for a model-shaped observation, clipped to [-1, 1]^4."""
        action, _ = self.model.predict(obs, deterministic=self.deterministic)
        return np.clip(np.asarray(action, dtype=np.float32).reshape(4), -1.0, 1.0)

    def next_probe(self, history: ProbeTable, obs: np.ndarray | None = None) -> np.ndarray | None:
        n = len(history)
        if n >= self.n_slots:
            return None  # the model has no slot for more probes
        if obs is None:
            obs = self._from_history(history)
        else:
            obs = self._rows_to_model(self.adapt(obs, n), min(n, self.n_slots))
        action = self.act(obs)
        if action[3] > 0:
            if n > 0:
                return None
            action[3] = -1.0  # the env ignores a stop before the first probe; make that explicit
        env_action = self._action_to_env(action)
        self._windows.append(float(self._phys(env_action[2], *self.context.measure_range_s)))
        return env_action
