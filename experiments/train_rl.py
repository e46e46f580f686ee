"""Train a Stable-Baselines3 probing policy for PlateRotation-v0 on the atlas backend and ship the best model.

    python experiments/train_rl.py [--algo ppo] [--seed 0] [--timesteps N] [--out agents/models/ppo_plate.zip]

Hyperparameters come from experiments/hyperparams/<algo>.yml (rl-zoo3 style: an entry per env id with n_envs,
n_timesteps, policy, learning_rate, n_steps, batch_size, gamma, ent_coef, policy_kwargs, env_kwargs, ...). The
training env is ``gym.make("PlateRotation-v0", physics="atlas", ...)`` vectorised with SB3's make_vec_env (a probe
costs microseconds there; the policy is meant to be evaluated on live physics, see experiments/eval_rl.py). An
EvalCallback scores the deterministic policy every ``eval_freq`` steps on the same seeded objects each time and
keeps the best model; that model is copied to ``--out`` with a JSON provenance file next to it (env kwargs,
timesteps, seed, evaluation reward, learning curve, date, versions). One torch thread: the machine is shared.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import platform
import shutil
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
import yaml

import plate_env  # noqa: F401 - registers the env

ENV_ID = "PlateRotation-v0"
ALGOS = ("ppo", "a2c", "sac")
#: Keys of the yml entry that are not arguments of the algorithm's constructor.
RUN_KEYS = ("n_envs", "n_timesteps", "policy", "env_kwargs", "eval_freq", "n_eval_episodes", "eval_seed",
            "correlated_instability")


def load_hyperparams(path: Path, env_id: str = ENV_ID) -> dict:
    with open(path) as fh:
        table = yaml.safe_load(fh)
    if env_id not in table:
        raise KeyError(f"{path} has no entry for {env_id!r} (entries: {sorted(table)})")
    return dict(table[env_id])


def env_kwargs_of(hp: dict) -> dict:
    kw = dict(hp.get("env_kwargs") or {})
    for key in ("amplitudes_deg", "f_band_hz", "omega_n_range_pi", "alpha_range_deg", "measure_range_s"):
        if key in kw:
            kw[key] = tuple(float(x) for x in kw[key])
    return kw


def physics_wrapper(options: dict | None):
    """A make_vec_env ``wrapper_class`` that swaps the atlas backend for one with correlated instability
    (plate_env.physics.atlas_physics.AtlasPhysics, ``instability_rho``/``instability_corr_hz``)."""
    if not options:
        return None
    from plate_env.physics.atlas_physics import AtlasPhysics


    def wrap(env):
        base = env.unwrapped
        base.physics = AtlasPhysics(atlas=base.physics.atlas, source=base.physics.source, model=base.physics.model,
                                    instability_rho=options.get("rho", 0.9),
                                    instability_corr_hz=options.get("corr_hz", 2.0))
        return env

    return wrap


def _rel(path: Path) -> str:
    """``path`` relative to the working directory when it lies under it (provenance without machine paths)."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def make_callback_class():
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--algo", default="ppo", choices=ALGOS)
    ap.add_argument("--hyperparams", type=Path, default=None, help="default: experiments/hyperparams/<algo>.yml")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timesteps", type=int, default=None, help="override n_timesteps")
    ap.add_argument("--out", type=Path, default=None, help="default: agents/models/<algo>_plate.zip")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)

    import stable_baselines3 as sb3
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.utils import set_random_seed

    hp_path = args.hyperparams or Path(__file__).parent / "hyperparams" / f"{args.algo}.yml"
    hp = load_hyperparams(hp_path)
    n_envs = int(hp.get("n_envs", 1))
    timesteps = int(args.timesteps or hp["n_timesteps"])
    env_kwargs = env_kwargs_of(hp)
    eval_freq = int(hp.get("eval_freq", 10_000))
    n_eval = int(hp.get("n_eval_episodes", 100))
    eval_seed = int(hp.get("eval_seed", 10_000))
    algo_kwargs = {k: v for k, v in hp.items() if k not in RUN_KEYS}
    out = args.out or Path("agents/models") / f"{args.algo}_plate.zip"

    set_random_seed(args.seed)
    wrap = physics_wrapper(hp.get("correlated_instability"))
    venv = make_vec_env(ENV_ID, n_envs=n_envs, seed=args.seed, env_kwargs=env_kwargs, wrapper_class=wrap)
    eval_env = make_vec_env(ENV_ID, n_envs=1, seed=eval_seed, env_kwargs=env_kwargs, wrapper_class=wrap)
    cls = {"ppo": sb3.PPO, "a2c": sb3.A2C, "sac": sb3.SAC}[args.algo]
    model = cls(hp.get("policy", "MlpPolicy"), venv, seed=args.seed, verbose=0, device="cpu", **algo_kwargs)
    with tempfile.TemporaryDirectory() as tmp:
        callback = make_callback_class()(eval_env, eval_freq=max(eval_freq // n_envs, 1), n_eval_episodes=n_eval,
                                         deterministic=True, best_model_save_path=tmp, log_path=tmp,
                                         eval_seed=eval_seed, verbose=0)
        t0 = time.perf_counter()
        model.learn(total_timesteps=timesteps, callback=callback, progress_bar=False)
        train_s = time.perf_counter() - t0
        best = Path(tmp) / "best_model.zip"
        if not best.exists():  # no evaluation ran (too few timesteps): keep the final model
            model.save(best)
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(best, out)
    best_i = int(np.argmax([p["eval_reward"] for p in callback.curve])) if callback.curve else None
    prov = {
        "algo": args.algo, "env_id": ENV_ID, "env_kwargs": {k: list(v) if isinstance(v, tuple) else v
                                                            for k, v in env_kwargs.items()},
        "hyperparams_file": _rel(hp_path), "hyperparams": hp, "timesteps": int(model.num_timesteps),
        "seed": args.seed, "n_envs": n_envs, "train_wall_s": round(train_s, 1), "torch_threads": args.threads,
        "eval": {"episodes": n_eval, "seed": eval_seed, "deterministic": True,
                 "best_reward": callback.best_mean_reward if callback.curve else None,
                 "best_at_timesteps": callback.curve[best_i]["timesteps"] if best_i is not None else None,
                 "curve": callback.curve},
        "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
        "versions": {"python": platform.python_version(), "stable_baselines3": sb3.__version__,
                     "torch": torch.__version__, "gymnasium": gym.__version__},
        "model_bytes": out.stat().st_size,
    }
    out.with_suffix(".json").write_text(json.dumps(prov, indent=2) + "\n")
    print(f"trained {model.num_timesteps} steps in {train_s:.0f} s; best eval reward {prov['eval']['best_reward']}"
          f" at {prov['eval']['best_at_timesteps']} steps -> {out} ({prov['model_bytes'] / 1024:.0f} kB)")
    venv.close()
    eval_env.close()


if __name__ == "__main__":
    main()
