"""Train a Stable-Baselines3 probing policy for PlateRotation-v0 on the atlas backend and ship the best model.

    python experiments/train_rl.py [--algo ppo] [--seed 0] [--timesteps N] [--out agents/models/ppo_plate.zip]

Public API only: the training envs are ``plate_env.sb3.make_sb3_vec_env(n_envs, seed, **env_kwargs)`` (one batched
physics call per step), every setting of the env an argument of PlateRotation-v0 (``env_kwargs``, including the
atlas backend's correlated instability through ``physics_options``). Hyperparameters come from
experiments/hyperparams/<algo>.yml in rl-zoo3's format (an entry per env id: n_envs, n_timesteps, policy,
policy_kwargs -- a dict or rl-zoo3's "dict(...)" string --, env_kwargs, and the algorithm's constructor arguments;
rl-zoo3's other run keys are refused here rather than ignored). An EvalCallback scores the deterministic policy
every ``--eval-freq`` steps on the same seeded objects each time and keeps the best model; that model is copied to
``--out``, its numpy forward pass exported beside it (plate_env_agents.ppo.export_policy: the agent then acts without
torch) and a JSON provenance file written (env kwargs, hyperparameters, timesteps, seed, evaluation reward, learning
curve, wall time, date, versions). One torch thread: the machine is shared.
"""

from __future__ import annotations

import argparse
import ast
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
from plate_env.env.sb3 import make_sb3_vec_env
from plate_env_agents.ppo import export_policy

ENV_ID = "PlateRotation-v0"
ALGOS = ("ppo", "a2c", "sac")
#: rl-zoo3's run keys this script honours (the rest of an entry goes to the algorithm's constructor).
RUN_KEYS = ("n_envs", "n_timesteps", "policy", "env_kwargs")
#: rl-zoo3's run keys this script does not implement: refused, not ignored.
UNSUPPORTED = ("normalize", "frame_stack", "env_wrapper", "vec_env_wrapper", "callback", "monitor_kwargs",
               "noise_type", "noise_std")


def load_hyperparams(path: Path, env_id: str = ENV_ID) -> dict:
    with open(path) as fh:
        table = yaml.safe_load(fh)
    if env_id not in table:
        raise KeyError(f"{path} has no entry for {env_id!r} (entries: {sorted(table)})")
    hp = dict(table[env_id])
    bad = [k for k in UNSUPPORTED if k in hp]
    if bad:
        raise ValueError(f"{path}: rl-zoo3 keys {bad} are not supported by experiments/train_rl.py")
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
    kw = dict(hp.get("env_kwargs") or {})
    for key in ("amplitudes_deg", "f_band_hz", "omega_n_range_pi", "alpha_range_deg", "measure_range_s"):
        if key in kw:
            kw[key] = tuple(float(x) for x in kw[key])
    return kw


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
    ap.add_argument("--eval-freq", type=int, default=8192, help="evaluate every this many steps (all envs)")
    ap.add_argument("--eval-episodes", type=int, default=100)
    ap.add_argument("--eval-seed", type=int, default=10_000)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)

    import stable_baselines3 as sb3
    from stable_baselines3.common.utils import set_random_seed

    hp_path = args.hyperparams or Path(__file__).parent / "hyperparams" / f"{args.algo}.yml"
    hp = load_hyperparams(hp_path)
    n_envs = int(hp.get("n_envs", 1))
    timesteps = int(args.timesteps or hp["n_timesteps"])
    env_kwargs = env_kwargs_of(hp)
    eval_freq, n_eval, eval_seed = args.eval_freq, args.eval_episodes, args.eval_seed
    algo_kwargs = {k: v for k, v in hp.items() if k not in RUN_KEYS}
    algo_kwargs["policy_kwargs"] = policy_kwargs_of(hp.get("policy_kwargs"))
    out = args.out or Path("agents/models") / f"{args.algo}_plate.zip"

    set_random_seed(args.seed)
    venv = make_sb3_vec_env(n_envs, seed=args.seed, **env_kwargs)
    eval_env = make_sb3_vec_env(1, seed=eval_seed, **env_kwargs)
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
    if args.algo in ("ppo", "a2c"):  # the agent acts in numpy from this export (SAC's actor is another network)
        export_policy(cls.load(out, device="cpu"), out)
    best_i = int(np.argmax([p["eval_reward"] for p in callback.curve])) if callback.curve else None
    prov = {
        "algo": args.algo, "env_id": ENV_ID, "env_kwargs": {k: list(v) if isinstance(v, tuple) else v
                                                            for k, v in env_kwargs.items()},
        "command": f"python experiments/train_rl.py --algo {args.algo} --seed {args.seed}"
                   + (f" --timesteps {args.timesteps}" if args.timesteps else ""),
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
