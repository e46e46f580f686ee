"""A trained Stable-Baselines3 probing policy (``plate-env build policy``), acting from the env observation.

The shipped model, ``agents/models/ppo_plate.zip``, was trained on ``PlateRotation-v0`` with ``physics="atlas"``
(probes answered from the tile-link response atlas in microseconds) and the settings the CLI's ``identify`` uses:
max_probes 30, plate amplitudes 3 and 12 deg, band 10-40 Hz, windows 0.25-2 s. Its provenance (env kwargs,
timesteps, seed, evaluation reward, date) is in ``ppo_plate.json`` next to it. The estimate is the atlas
posterior (``method = "atlas"``), the estimator the policy was rewarded with.

Start-up. Importing torch and Stable-Baselines3 takes seconds, so the shipped policy acts in numpy: its weights
are exported beside the zip (``ppo_plate.npz``, :func:`export_policy`, written by plate-env build policy, with the
zip's SHA-256 so a stale export is never used) and the MLP's forward pass (Linear-Tanh layers, then the action
mean; deterministic) is a few matrix products. Its actions equal ``model.predict(obs, deterministic=True)`` to
float32 rounding (tests/test_agents_ppo.py). A model without an export (``sb3:model.zip``), another algorithm or
``deterministic=False`` loads Stable-Baselines3 and acts through ``model.predict``.

``next_probe`` returns the raw action (f_p, amplitude, window and stop, each in [-1, 1]; the episode loop passes it
to the env as is), or None when the stop component is positive.

Other budgets. The observation has one 7-feature row per probe slot, so its length depends on ``max_probes``.
An observation of another length is re-laid out to the model's: the filled rows are copied (up to the model's
slot count), the probes-left fraction is recomputed against the model's slot count and the sim-seconds-left
fraction is passed through. Once the model's slots are full the agent stops. Without an observation (``obs``
None) the agent rebuilds one from the probe table and the windows it chose itself.

Other band, amplitudes or windows. The model's actions and observation rows are in its training coordinates
(``ppo_plate.json`` env_kwargs; the env's defaults without one); when the env's differ, the agent translates both
ways through physical units (Hz, deg, s), clipping to the env's ranges and taking the nearest amplitude (a warning
names amplitudes the policy never saw). With the training settings the action is the model's, untouched.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from pathlib import Path

import numpy as np

from plate_env.core.files import check_regular, read_json, write_atomic
from plate_env.core.probe_table import ProbeTable
from plate_env.env.codec import N_FEATURES, Codec, phys
from plate_env.env.protocol import Agent, ProbeContext

#: The model shipped with the package.
DEFAULT_MODEL = Path(__file__).parent / "models" / "ppo_plate.zip"
#: Stable-Baselines3 algorithms a model file may hold.
SB3_ALGOS = ("ppo", "a2c", "sac")
#: Activations of SB3's MlpPolicy that the numpy forward pass knows.
ACTIVATIONS = {"Tanh": np.tanh, "ReLU": lambda x: np.maximum(x, 0.0)}


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def export_policy(model, zip_path: str | Path) -> Path:
    """Write the deterministic forward pass of an SB3 ``ActorCriticPolicy`` (PPO/A2C MlpPolicy, Box actions) beside
    ``zip_path`` as ``.npz``: the policy network's Linear layers, the action head, the activation's name and the
    zip's SHA-256. Returns the file written."""
    policy = model.policy
    sd = {k: v.detach().cpu().numpy() for k, v in policy.state_dict().items()}
    layers = sorted({int(k.split(".")[2]) for k in sd if k.startswith("mlp_extractor.policy_net.")})
    out = {}
    for i, j in enumerate(layers):
        out[f"w{i}"] = sd[f"mlp_extractor.policy_net.{j}.weight"]
        out[f"b{i}"] = sd[f"mlp_extractor.policy_net.{j}.bias"]
    n = len(layers)
    path = Path(zip_path).with_suffix(".npz")
    write_atomic(path, lambda tmp: np.savez(
        tmp, **out, n_hidden=np.array(n), w_out=sd["action_net.weight"], b_out=sd["action_net.bias"],
        activation=np.array(type(policy.activation_fn()).__name__), zip_sha256=np.array(_sha256(zip_path)),
        obs_dim=np.array(int(model.observation_space.shape[0]))), "policy export")
    return path


class NumpyPolicy:
    """The deterministic action of an exported MlpPolicy (:func:`export_policy`), in numpy (no torch)."""

    def __init__(self, path: Path) -> None:
        with np.load(check_regular(path, "sb3 model export")) as d:
            n = int(d["n_hidden"])
            self.layers = [(d[f"w{i}"], d[f"b{i}"]) for i in range(n)]
            self.out = (d["w_out"], d["b_out"])
            self.act = ACTIVATIONS[str(d["activation"])]
            self.zip_sha256 = str(d["zip_sha256"])
            self.obs_dim = int(d["obs_dim"])

    def predict(self, obs: np.ndarray) -> np.ndarray:
        h = np.asarray(obs, dtype=np.float32)
        for w, b in self.layers:
            h = self.act(h @ w.T + b)
        return h @ self.out[0].T + self.out[1]


#: The policy class each algorithm's zip must name (read from its metadata, never unpickled).
POLICY_CLASSES = {"ppo": "ActorCriticPolicy", "a2c": "ActorCriticPolicy", "sac": "SACPolicy"}
#: Pickled entries of an SB3 zip that only training reads (replaced by harmless stand-ins on load).
TRAINING_ONLY = ("lr_schedule", "clip_range", "clip_range_vf", "learning_rate", "ent_coef", "target_entropy",
                 "_last_obs", "_last_original_obs", "_last_episode_starts", "ep_info_buffer", "ep_success_buffer",
                 "rollout_buffer_class", "replay_buffer_class", "rollout_buffer_kwargs", "replay_buffer_kwargs",
                 "action_noise")


def _no_schedule(_progress: float) -> float:
    return 0.0


def safe_custom_objects(path: str | Path, algo: str) -> dict:
    """Everything Stable-Baselines3 would unpickle from a model zip's metadata, replaced before it does: SB3 stores
    the policy class, the spaces and the schedules with cloudpickle, and unpickling them runs whatever code the zip
    carries. Here the spaces are rebuilt from their readable fields and checked against PlateRotation-v0's (an
    observation of ``k * N_FEATURES + 2`` values in [-10, 10], an action of 4 in [-1, 1]), the policy class is the
    algorithm's own (checked against the name the zip gives), training-only entries become stand-ins, and a zip
    with any other pickled entry is refused. ValueError naming the file and the problem. The weights
    (``policy.pth``) are read by torch's loader as SB3 does; a model zip remains a file you should trust."""
    import zipfile

    import gymnasium as gym
    import stable_baselines3 as sb3

    where = f"sb3 model {str(path)!r}"
    check_regular(path, "sb3 model")
    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{where}: not a Stable-Baselines3 zip ({exc})") from None
    out: dict = {}
    for key, value in data.items():
        if not (isinstance(value, dict) and ":serialized:" in value):
            continue
        if key in ("observation_space", "action_space"):
            kind = str(value.get(":type:", ""))
            raw = value.get("_shape")
            shape = tuple(raw) if isinstance(raw, list) and all(isinstance(x, int) for x in raw) else ()
            want = f"an observation of k * {N_FEATURES} + 2 values" if key == "observation_space" else "4 values"
            ok = "gymnasium.spaces.box.Box" in kind and len(shape) == 1 and (
                (shape[0] - 2) % N_FEATURES == 0 and shape[0] > 2 if key == "observation_space" else shape[0] == 4)
            if not ok:
                raise ValueError(f"{where}: its {key.replace('_', ' ')} is {kind or '?'} of shape {shape}, not "
                                 f"PlateRotation-v0's ({want}): a model for another environment")
            lim = 10.0 if key == "observation_space" else 1.0
            out[key] = gym.spaces.Box(-lim, lim, shape, dtype=np.float32)
        elif key == "policy_class":
            init = str(value.get("__init__", ""))
            expected = POLICY_CLASSES[algo]
            if f"{expected}.__init__" not in init:
                found = init.split(".__init__")[0].removeprefix("<function ") or "an unknown class"
                raise ValueError(f"{where}: a {found} policy, not the {expected} of sb3:{algo}: (name the algorithm "
                                 "it was trained with, e.g. sb3:ppo:model.zip)")
            out[key] = getattr(sb3, algo.upper()).policy_aliases["MlpPolicy"]
        elif key in TRAINING_ONLY:
            out[key] = _no_schedule if key in ("lr_schedule", "clip_range", "clip_range_vf", "learning_rate") else None
        else:
            raise ValueError(f"{where}: stores a pickled {key!r}; loading it would run code from the file: refused")
    return out


class PPOAgent(Agent):
    """Probing by a trained SB3 policy; ``path`` is its zip (default: the shipped PPO model), ``algo`` its
    algorithm (PPO by default; A2C and SAC load through Stable-Baselines3)."""

    name = "ppo"
    method = "atlas"

    def __init__(self, path: str | Path | None = None, deterministic: bool = True, device: str = "cpu",
                 algo: str = "ppo") -> None:
        if algo not in SB3_ALGOS:
            raise ValueError(f"algo = {algo!r}: choose one of {SB3_ALGOS}")
        self.path = Path(path) if path is not None else DEFAULT_MODEL
        if not self.path.exists():
            raise FileNotFoundError(f"no PPO model at {self.path}; train one with plate-env build policy --out "
                                    "MODEL.zip")
        check_regular(self.path, "sb3 model")
        self.algo = algo
        self.deterministic = deterministic
        self.device = device
        self.model_sha256 = _sha256(self.path)
        export = self.path.with_suffix(".npz")
        self._numpy = None
        if deterministic and algo in ("ppo", "a2c") and export.exists():
            pol = NumpyPolicy(export)
            if pol.zip_sha256 == self.model_sha256:
                self._numpy = pol
        self._sb3 = None if self._numpy is not None else self._load_sb3()
        self.obs_dim = self._numpy.obs_dim if self._numpy is not None else int(
            self._sb3.observation_space.shape[0])
        self.n_slots = Codec.slots_of(self.obs_dim)
        meta = self.path.with_suffix(".json")
        self.provenance = read_json(meta, "sb3 model provenance") if meta.exists() else {}
        env_kwargs = self.provenance.get("env_kwargs", {})
        self.method = env_kwargs.get("method", "atlas")
        self.trained_band = tuple(env_kwargs.get("f_band_hz", (10.0, 40.0)))
        self.trained_amps = tuple(env_kwargs.get("amplitudes_deg", (3.0, 12.0)))
        self.trained_windows = tuple(env_kwargs.get("measure_range_s", (0.25, 2.0)))
        #: The model's observation/action layout (its training settings) and, after reset, the env's.
        self.codec = Codec(self.trained_band, self.trained_amps, self.trained_windows, self.n_slots)
        self.env_codec: Codec | None = None
        self._windows: list[float] = []

    def _load_sb3(self):
        import pickle

        import stable_baselines3 as sb3

        custom = safe_custom_objects(self.path, self.algo)
        try:
            return getattr(sb3, self.algo.upper()).load(self.path, device=self.device, custom_objects=custom)
        except pickle.UnpicklingError:  # torch's weights-only loader met something besides tensors
            raise ValueError(f"sb3 model {str(self.path)!r}: its weights (policy.pth and the other .pth files) hold "
                             "pickled objects besides tensors; loading them could run code from the file: "
                             "refused") from None

    @property
    def model(self):
        """The Stable-Baselines3 model (loaded on first use when the agent acts in numpy)."""
        if self._sb3 is None:
            self._sb3 = self._load_sb3()
        return self._sb3

    @property
    def backend(self) -> str:
        """``"numpy"`` (the exported forward pass) or ``"sb3"``."""
        return "numpy" if self._numpy is not None else "sb3"

    def fingerprint(self) -> str:
        """The model file's SHA-256 (names this policy in benchmark records)."""
        return self.model_sha256

    def reset(self, context: ProbeContext, rng: np.random.Generator) -> None:
        super().reset(context, rng)
        self._windows = []
        self.env_codec = Codec.of(context)
        foreign = [a for a in context.amplitudes_deg if not np.any(np.isclose(self.trained_amps, a))]
        if foreign:
            warnings.warn(f"PPO policy trained on amplitudes {self.trained_amps} deg, the env offers {foreign}: "
                          "its amplitude choices are mapped to the nearest one", stacklevel=2)

    # ----------------------------------------------------------------- observation
    def _from_history(self, history: ProbeTable) -> np.ndarray:
        """The model's observation rebuilt from the probe table (windows: the ones this agent chose, else 1 s)."""
        n = min(len(history), self.n_slots)
        rows = [(history.f_p_hz[i], history.a_p_deg[i], history.omega_b_deg_s[i], history.stderr_deg_s[i],
                 history.unstable[i], self._windows[i] if i < len(self._windows) else 1.0) for i in range(n)]
        # the simulated-seconds budget is not in the table: unlimited, as in training
        return self.codec.observation(rows, max(1.0 - len(history) / self.n_slots, 0.0), 1.0)

    def adapt(self, obs: np.ndarray, n_probes: int) -> np.ndarray:
        """An env observation laid out for the model (see the module docstring for other budgets)."""
        return self.codec.resized(obs, n_probes)

    # ----------------------------------------------------------------- policy
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The policy's action for a model-shaped observation, clipped to [-1, 1]^4."""
        if self._numpy is not None:
            return np.clip(self._numpy.predict(obs).astype(np.float32).reshape(4), -1.0, 1.0)
        action, _ = self.model.predict(obs, deterministic=self.deterministic)
        return np.clip(np.asarray(action, dtype=np.float32).reshape(4), -1.0, 1.0)

    def next_probe(self, history: ProbeTable, obs: np.ndarray | None = None) -> np.ndarray | None:
        n = len(history)
        if n >= self.n_slots:
            return None  # the model has no slot for more probes
        if obs is None:
            obs = self._from_history(history)
        else:
            obs = self.codec.rows_from(self.adapt(obs, n), min(n, self.n_slots), self.env_codec)
        action = self.act(obs)
        if action[3] > 0:
            if n > 0:
                return None
            action[3] = -1.0  # the env ignores a stop before the first probe; make that explicit
        env_action = self.env_codec.action_from(action, self.codec)
        self._windows.append(float(phys(env_action[2], *self.context.measure_range_s)))
        return env_action
