"""Train a Stable-Baselines3 probing policy for PlateRotation-v0 (``plate-env build policy``), from hyperparameters
installed with this package.

The hyperparameters are rl-zoo3's format, one entry per env id (:func:`hyperparams_file`,
``plate_env_agents/hyperparams/<algo>.yml``; rl-zoo3 reads the same entries through :mod:`plate_env_agents.zoo`):
``n_envs``, ``n_timesteps``, ``policy``, ``policy_kwargs`` (a dict or rl-zoo3's ``"dict(...)"`` string, read
without eval), ``env_kwargs`` (PlateRotation-v0's arguments) and the algorithm's constructor arguments; rl-zoo3's
other run keys are refused, not ignored.

Training uses the public API only: ``plate_env.env.sb3.make_sb3_vec_env(n_envs, seed, **env_kwargs)``. With
``eval_freq`` > 0 the deterministic policy is scored every ``eval_freq`` steps on the same seeded objects and the
best model is kept; with 0 the last model is. The model's numpy forward pass is exported beside it
(:func:`plate_env_agents.ppo.export_policy`: ``make_agent("ppo")`` then acts without torch) and its metadata written
to ``OUT.json``: the build record (command, package version, git commit), seed, hyperparameters and their file,
timesteps run, evaluation curve, wall time, torch threads and library versions.

Determinism: with the same seed, hyperparameters, torch thread count, torch build and machine, two trainings give
the same parameters, bit for bit (tests/test_train.py trains twice in one process). Across machines or torch builds
nothing is promised: float reductions may round differently.
"""

from __future__ import annotations

import ast
import datetime as dt
import json
import platform
import shutil
import tempfile
import time
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

from plate_env.core.files import read_text, write_atomic, write_text_atomic

ENV_ID = "PlateRotation-v0"
ALGOS = ("ppo", "a2c", "sac")
#: rl-zoo3's run keys honoured here (the rest of an entry goes to the algorithm's constructor).
RUN_KEYS = ("n_envs", "n_timesteps", "policy", "env_kwargs")
#: rl-zoo3's run keys not implemented here: refused, not ignored.
UNSUPPORTED = ("normalize", "frame_stack", "env_wrapper", "vec_env_wrapper", "callback", "monitor_kwargs",
               "noise_type", "noise_std")


def hyperparams_file(algo: str = "ppo"):
    """The installed hyperparameter file of ``algo`` (an ``importlib.resources`` traversable:
    ``plate_env_agents/hyperparams/<algo>.yml``); ValueError naming the files shipped when there is none."""
    folder = resources.files("plate_env_agents") / "hyperparams"
    path = folder / f"{algo}.yml"
    if not path.is_file():
        shipped = sorted(p.name for p in folder.iterdir() if p.name.endswith(".yml"))
        raise ValueError(f"no hyperparameters for {algo!r} installed with plate_env_agents (shipped: {shipped})")
    return path


def load_hyperparams(path=None, env_id: str = ENV_ID, algo: str = "ppo") -> dict:
    """The entry for ``env_id`` of a hyperparameter file (default: the installed one of ``algo``)."""
    import yaml

    if path is None:  # the installed file (a package resource)
        path = hyperparams_file(algo)
        text = path.read_text()
    else:  # a user's, refused unless a regular file (plate_env.core.files)
        path, text = Path(path), read_text(path, "hyperparameters")
    try:
        table = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"hyperparameters {str(path)!r}: {exc}") from None
    if not isinstance(table, dict) or env_id not in table:
        raise ValueError(f"hyperparameters {str(path)!r} have no entry for {env_id!r}")
    hp = dict(table[env_id])
    bad = [k for k in UNSUPPORTED if k in hp]
    if bad:
        raise ValueError(f"hyperparameters {str(path)!r}: rl-zoo3 keys {bad} are not supported by plate-env build "
                         "policy")
    return hp


def policy_kwargs_of(value) -> dict:
    """rl-zoo3's ``policy_kwargs``: a dict, or a ``"dict(key=literal, ...)"`` string (read without eval)."""
    if value is None or isinstance(value, dict):
        return dict(value or {})
    call = ast.parse(value, mode="eval").body
    if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name) and call.func.id == "dict"
            and not call.args):
        raise ValueError(f"policy_kwargs {value!r}: expected dict(key=literal, ...)")
    return {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords}


def env_kwargs_of(hp: dict) -> dict:
    """PlateRotation-v0's arguments of an entry (its ``env_kwargs``, lists of numbers as tuples)."""
    kw = dict(hp.get("env_kwargs") or {})
    for key in ("amplitudes_deg", "f_band_hz", "omega_n_range_pi", "alpha_range_deg", "measure_range_s"):
        if key in kw:
            kw[key] = tuple(float(x) for x in kw[key])
    return kw


def _callback_class():
    import numpy as np
    from stable_baselines3.common.callbacks import EvalCallback

    class SeededEvalCallback(EvalCallback):
        """EvalCallback that reseeds the eval env before every evaluation, so every evaluation sees the same
        objects and the best model is chosen on a fixed set rather than on whichever objects came up."""

        def __init__(self, *args, eval_seed: int = 10_000, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.eval_seed = eval_seed
            self.curve: list[dict] = []
            self.t0 = time.perf_counter()

        def _on_step(self) -> bool:
            due = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0
            if due:
                self.eval_env.seed(self.eval_seed)
            ok = super()._on_step()
            if due:
                self.curve.append({"timesteps": int(self.num_timesteps),
                                   "wall_s": round(time.perf_counter() - self.t0, 1),
                                   "eval_reward": float(self.last_mean_reward),
                                   "eval_ep_length": float(np.mean(self.evaluations_length[-1]))})
                p = self.curve[-1]
                print(f"{p['timesteps']:8d} steps  {p['wall_s']:6.1f} s  eval reward {p['eval_reward']:7.4f}  "
                      f"probes {p['eval_ep_length']:5.2f}", flush=True)
            return ok

    return SeededEvalCallback


def _check(seed: int, timesteps: int | None, eval_freq: int, eval_episodes: int, threads: int) -> None:
    for name, value, lo in (("--seed", seed, 0), ("--eval-freq", eval_freq, 0), ("--eval-episodes", eval_episodes, 1),
                            ("--threads", threads, 1)) + ((("--timesteps", timesteps, 1),) if timesteps is not None
                                                          else ()):
        if value < lo:
            raise ValueError(f"{name} {value}: needs {lo} or more")


def train_policy(out: str | Path, record: dict, *, algo: str = "ppo", hyperparams: str | Path | None = None,
                 env_id: str = ENV_ID, seed: int = 0, timesteps: int | None = None, eval_freq: int = 8192,
                 eval_episodes: int = 100, eval_seed: int = 10_000, threads: int = 1) -> dict:
    """Train ``algo`` (:data:`ALGOS`) with the installed hyperparameters' entry for ``env_id`` (or ``hyperparams``'s;
    ``PlateRotation-v0`` by default, ``PlateRotationAtlas-v1`` for the faithful rigid tiles' atlas),
    write the model to ``out``, its numpy export (PPO/A2C) beside it and its metadata to ``out`` with ``.json``;
    returns the metadata. ``record`` is the build record (command, plate_env version, commit). Arguments are
    checked before any work (ValueError naming the value)."""
    if algo not in ALGOS:
        raise ValueError(f"algo {algo!r}: one of {list(ALGOS)}")
    _check(seed, timesteps, eval_freq, eval_episodes, threads)
    hp_path = hyperparams_file(algo) if hyperparams is None else Path(hyperparams)
    hp = load_hyperparams(hp_path, env_id=env_id, algo=algo)
    out = Path(out)
    if not out.parent.is_dir():
        raise ValueError(f"--out {str(out)!r}: the folder {str(out.parent)!r} does not exist")
    import gymnasium as gym
    import stable_baselines3 as sb3
    import torch
    from stable_baselines3.common.utils import set_random_seed

    from plate_env.env.sb3 import make_sb3_vec_env
    from plate_env_agents.ppo import export_policy

    torch.set_num_threads(threads)
    n_envs = int(hp.get("n_envs", 1))
    steps = int(timesteps or hp["n_timesteps"])
    env_kwargs = env_kwargs_of(hp)
    algo_kwargs = {k: v for k, v in hp.items() if k not in RUN_KEYS}
    algo_kwargs["policy_kwargs"] = policy_kwargs_of(hp.get("policy_kwargs"))
    set_random_seed(seed)
    venv = make_sb3_vec_env(n_envs, seed=seed, **env_kwargs)
    eval_env = make_sb3_vec_env(1, seed=eval_seed, **env_kwargs) if eval_freq else None
    cls = {"ppo": sb3.PPO, "a2c": sb3.A2C, "sac": sb3.SAC}[algo]
    model = cls(hp.get("policy", "MlpPolicy"), venv, seed=seed, verbose=0, device="cpu", **algo_kwargs)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            callback = None
            if eval_env is not None:
                callback = _callback_class()(eval_env, eval_freq=max(eval_freq // n_envs, 1),
                                             n_eval_episodes=eval_episodes, deterministic=True,
                                             best_model_save_path=tmp, log_path=tmp, eval_seed=eval_seed, verbose=0)
            t0 = time.perf_counter()
            model.learn(total_timesteps=steps, callback=callback, progress_bar=False)
            train_s = time.perf_counter() - t0
            best = Path(tmp) / "best_model.zip"
            if not best.exists():  # no evaluation (eval_freq 0, or too few steps): the last model
                model.save(best)
            write_atomic(out, lambda tmp: shutil.copyfile(best, tmp), "--out")
    finally:
        venv.close()
        if eval_env is not None:
            eval_env.close()
    if algo in ("ppo", "a2c"):  # the agent acts in numpy from this export (SAC's actor is another network)
        export_policy(cls.load(out, device="cpu"), out)
    curve = callback.curve if callback is not None else []
    best_i = max(range(len(curve)), key=lambda i: curve[i]["eval_reward"]) if curve else None
    meta = {
        "algo": algo, "env_id": env_id,
        "env_kwargs": {k: list(v) if isinstance(v, tuple) else v for k, v in env_kwargs.items()},
        "build": record, "command": record.get("command"),
        "hyperparams_file": (f"plate_env_agents/hyperparams/{algo}.yml (installed)" if hyperparams is None
                             else str(hyperparams)),
        "hyperparams": hp, "timesteps": int(model.num_timesteps), "seed": seed, "n_envs": n_envs,
        "train_wall_s": round(train_s, 1), "torch_threads": threads,
        "eval": {"episodes": eval_episodes, "seed": eval_seed, "deterministic": True, "freq": eval_freq,
                 "best_reward": callback.best_mean_reward if curve else None,
                 "best_at_timesteps": curve[best_i]["timesteps"] if best_i is not None else None, "curve": curve},
        "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
        "versions": {"python": platform.python_version(), "stable_baselines3": sb3.__version__,
                     "torch": torch.__version__, "gymnasium": gym.__version__},
        "model_bytes": out.stat().st_size,
    }
    write_text_atomic(out.with_suffix(".json"), json.dumps(meta, indent=2) + "\n", "--out")
    return meta


__all__: Sequence[str] = ("ALGOS", "ENV_ID", "env_kwargs_of", "hyperparams_file", "load_hyperparams",
                          "policy_kwargs_of", "train_policy")
