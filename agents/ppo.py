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
float32 rounding (tests/test_agents_ppo.py). A model without an export (``sb3:model.zip``), another algorithm (A2C,
SAC, TD3, DDPG) or ``deterministic=False`` acts through the SB3 policy's ``predict``, built from the zip without
unpickling anything (:mod:`plate_env_agents.sb3_zip`).

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
names amplitudes the policy never saw). With the training settings the action is the model's, untouched. A
model without a sidecar is taken to have trained on the defaults, and an env with other settings is refused
at reset (the message says which file to write) rather than scored in coordinates guessed for it.
"""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path

import numpy as np

from plate_env.core.files import check_regular, read_json, write_atomic
from plate_env.core.probe_table import ProbeTable
from plate_env.env.codec import Codec, phys
from plate_env.env.protocol import Agent, ProbeContext
from plate_env_agents.sb3_zip import SB3_ALGOS, inspect_zip, load_policy

#: The model shipped with the package.
DEFAULT_MODEL = Path(__file__).parent / "models" / "ppo_plate.zip"
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


class PPOAgent(Agent):
    """Probing by a trained SB3 policy; ``path`` is its zip (default: the shipped PPO model), ``algo`` its
    algorithm (one of :data:`SB3_ALGOS`, checked against the zip's policy class; None: the zip's). Any of them
    loads without unpickling anything (:mod:`plate_env_agents.sb3_zip`)."""

    name = "ppo"
    method = "atlas"

    def __init__(self, path: str | Path | None = None, deterministic: bool = True, device: str = "cpu",
                 algo: str | None = None) -> None:
        if algo is not None and algo not in SB3_ALGOS:
            raise ValueError(f"algo = {algo!r}: choose one of {SB3_ALGOS} (the algorithms a Box action space "
                             "admits) or None (the zip's)")
        self.path = Path(path) if path is not None else DEFAULT_MODEL
        if not self.path.exists():
            raise FileNotFoundError(f"no SB3 model at {self.path} (a zip of {', '.join(SB3_ALGOS)}); train one with "
                                    "plate-env build policy --out MODEL.zip")
        check_regular(self.path, "sb3 model")
        self.algo = inspect_zip(self.path, algo).algo  # refuses a zip it cannot load before any work
        self.deterministic = deterministic
        self.device = device
        self.model_sha256 = _sha256(self.path)
        export = self.path.with_suffix(".npz")
        self._numpy = None
        if deterministic and self.algo in ("ppo", "a2c") and export.exists():
            pol = NumpyPolicy(export)
            if pol.zip_sha256 == self.model_sha256:
                self._numpy = pol
        self._sb3 = None if self._numpy is not None else self._load_sb3()
        self.obs_dim = self._numpy.obs_dim if self._numpy is not None else int(
            self._sb3.observation_space.shape[0])
        self.n_slots = Codec.slots_of(self.obs_dim)
        meta = self.path.with_suffix(".json")
        #: Whether a sidecar (``MODEL.json``) says how the model was trained; without one the env's defaults are
        #: assumed and an env with other settings is refused (:meth:`reset`).
        self._has_sidecar = meta.exists()
        self.provenance = read_json(meta, "sb3 model provenance") if self._has_sidecar else {}
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
        return load_policy(self.path, self.algo, self.device)[0]

    @property
    def model(self):
        """The Stable-Baselines3 policy (``BasePolicy``, :func:`plate_env_agents.sb3_zip.load_policy`; loaded on
        first use when the agent acts in numpy); ``model.predict`` is the trained model's."""
        if self._sb3 is None:
            self._sb3 = self._load_sb3()
        return self._sb3

    @property
    def backend(self) -> str:
        """``"numpy"`` (the exported forward pass) or ``"sb3"``."""
        return "numpy" if self._numpy is not None else "sb3"

    def fingerprint(self) -> str:
        """The model file's SHA-256 (names this policy in benchmark records; the training settings read from its
        sidecar are in the record's key too, as public options: tests/test_sb3_zips.py)."""
        return self.model_sha256

    def reset(self, context: ProbeContext, rng: np.random.Generator) -> None:
        super().reset(context, rng)
        self._windows = []
        self.env_codec = Codec.of(context)
        if not self._has_sidecar and not self.codec.same_coordinates(self.env_codec):
            raise ValueError(
                f"sb3 model {str(self.path)!r} has no sidecar {self.path.with_suffix('.json').name} saying which "
                f"settings it was trained with, and this env's differ from the defaults it would assume "
                f"(band {self.env_codec.f_band_hz} Hz, amplitudes {self.env_codec.amplitudes_deg} deg, windows "
                f"{self.env_codec.measure_range_s} s; defaults {self.codec.f_band_hz}, {self.codec.amplitudes_deg}, "
                f"{self.codec.measure_range_s}): write {self.path.with_suffix('.json')} with "
                "{\"env_kwargs\": {...}}, the env kwargs it trained with (f_band_hz, amplitudes_deg, "
                "measure_range_s, method; {} for the defaults), e.g. from rl-zoo3's config.yml beside the zip, "
                "rather than have them guessed")
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
