"""How long `plate-env build policy` takes here, and how many steps SB3's `learn(n)` really runs (issue 28 item 22).

    nice -n 5 python experiments/ppo_timing.py [--steps 16384] [--eval-episodes 100]

1. The installed PPO hyperparameters (plate_env_agents/hyperparams/ppo.yml: 8 envs x 128 steps a rollout), trained
   for ``--steps`` steps without evaluation, one torch thread: steps per second, extrapolated to the file's
   n_timesteps (what SB3 runs for it: whole rollouts).
2. One evaluation as `plate-env build policy` runs it every 8192 steps (``--eval-episodes`` deterministic episodes).
3. The README snippet's PPO (SB3's default n_steps 2048, 8 envs) with `learn(4096)`: the steps it actually runs.

Writes experiments/results/ppo_timing.json (the source of truth) and .md from it, with the load (uptime) before and
after. Times are wall seconds on a shared machine: the load is part of the number.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from common import commit, load

RESULTS = Path(__file__).parent / "results"


def write_md(r: dict) -> None:
    t, e, s = r["train"], r["evaluation"], r["readme_snippet"]
    lines = ["# Training time of the shipped PPO configuration, and SB3's rollout rounding", "",
             f"`{r['command']}` at commit `{r['commit']}`; load average {r['load_before']} before, {r['load_after']} "
             f"after (2 cores, shared); torch {r['torch']}, one thread.", "",
             "| what | steps run | wall s | steps/s |", "|---|---|---|---|",
             f"| installed `ppo.yml` ({t['n_envs']} envs x {t['n_steps']}), `learn({t['asked']})`, no evaluation "
             f"| {t['steps']:,} | {t['wall_s']:.1f} | {t['steps_per_s']:.0f} |",
             f"| one evaluation ({e['episodes']} deterministic episodes) | {e['steps']:,} | {e['wall_s']:.1f} | "
             f"{e['steps'] / e['wall_s']:.0f} |",
             f"| README snippet (8 envs x 2048), `learn({s['asked']})` | {s['steps']:,} | {s['wall_s']:.1f} | "
             f"{s['steps'] / s['wall_s']:.0f} |", "",
             f"Extrapolated: `n_timesteps` {t['n_timesteps']:,} runs {t['full_steps']:,} steps (whole rollouts of "
             f"{t['n_envs'] * t['n_steps']:,}), about {t['full_train_s'] / 60:.0f} min of training; with an "
             f"evaluation every 8192 steps ({t['n_evaluations']} of them, as `plate-env build policy` does by default) "
             f"about {t['full_with_eval_s'] / 60:.0f} min in all. The shipped model's own run took "
             f"{r['shipped_train_wall_s'] / 60:.0f} min (agents/models/ppo_plate.json, another load).", "",
             f"SB3 finishes the rollout it is in: `learn(n)` runs ceil(n / (n_steps x n_envs)) rollouts, so "
             f"`learn({s['asked']})` ran {s['steps']:,} steps and `learn(100_000)` runs "
             f"{math.ceil(100_000 / 16384) * 16384:,}."]
    (RESULTS / "ppo_timing.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=16384)
    ap.add_argument("--eval-episodes", type=int, default=100)
    ap.add_argument("--md", action="store_true", help="only rewrite the .md from the .json")
    args = ap.parse_args()
    if args.md:
        write_md(json.loads((RESULTS / "ppo_timing.json").read_text()))
        return
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.evaluation import evaluate_policy

    from plate_env.env.sb3 import make_sb3_vec_env
    from plate_env_agents.train import env_kwargs_of, load_hyperparams, policy_kwargs_of

    torch.set_num_threads(1)
    before = load()
    hp = load_hyperparams()
    kw = env_kwargs_of(hp)
    algo = {k: v for k, v in hp.items() if k not in ("n_envs", "n_timesteps", "policy", "env_kwargs")}
    algo["policy_kwargs"] = policy_kwargs_of(hp["policy_kwargs"])
    venv = make_sb3_vec_env(hp["n_envs"], seed=0, **kw)
    model = PPO(hp["policy"], venv, seed=0, device="cpu", **algo)
    t0 = time.perf_counter()
    model.learn(args.steps)
    wall = time.perf_counter() - t0
    per_rollout = hp["n_envs"] * hp["n_steps"]
    full = math.ceil(hp["n_timesteps"] / per_rollout) * per_rollout
    train = {"asked": args.steps, "steps": int(model.num_timesteps), "wall_s": wall, "n_envs": hp["n_envs"],
             "n_steps": hp["n_steps"], "steps_per_s": model.num_timesteps / wall, "n_timesteps": hp["n_timesteps"],
             "full_steps": full, "full_train_s": full * wall / model.num_timesteps}
    print(train, flush=True)
    eval_env = make_sb3_vec_env(1, seed=10_000, **kw)
    t0 = time.perf_counter()
    _, lengths = evaluate_policy(model, eval_env, n_eval_episodes=args.eval_episodes, deterministic=True,
                                 return_episode_rewards=True)
    ev = {"episodes": args.eval_episodes, "steps": int(sum(lengths)), "wall_s": time.perf_counter() - t0}
    print(ev, flush=True)
    train["n_evaluations"] = full // 8192
    train["full_with_eval_s"] = train["full_train_s"] + train["n_evaluations"] * ev["wall_s"]
    venv.close()
    eval_env.close()
    snippet_model = PPO("MlpPolicy", make_sb3_vec_env(n_envs=8, physics="atlas", seed=0), seed=0, device="cpu")
    t0 = time.perf_counter()
    snippet_model.learn(4096)
    snippet = {"asked": 4096, "steps": int(snippet_model.num_timesteps), "wall_s": time.perf_counter() - t0}
    print(snippet, flush=True)
    shipped = json.loads((Path(__file__).parents[1] / "agents" / "models" / "ppo_plate.json").read_text())
    r = {"command": " ".join(["python experiments/ppo_timing.py", *sys.argv[1:]]), "commit": commit(),
         "torch": torch.__version__, "load_before": before, "load_after": load(), "train": train, "evaluation": ev,
         "readme_snippet": snippet, "shipped_train_wall_s": shipped["train_wall_s"]}
    (RESULTS / "ppo_timing.json").write_text(json.dumps(r, indent=1) + "\n")
    write_md(r)


if __name__ == "__main__":
    main()
