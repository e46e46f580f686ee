"""tianshou 2.0 PPO on the env ids, without a wrapper (issue 38: "tianshou PPO trains for 20k steps on v0 and v1").

    python experiments/tianshou_ppo.py [--steps 20000] [--episodes 100] [--ids PlateRotationAtlas-v0 ...]

For each id: tianshou's own PPO (its ``ProbabilisticActorPolicy`` + ``PPO`` + ``OnPolicyTrainer``, 4 envs in a
``DummyVectorEnv``, default PPO settings but for a 2,048-step collection and 64x64 nets) trains for ``--steps`` env
steps on ``gym.make(id)`` as registered (no wrapper: tianshou's ``Collector`` stacks the env's info into its
``Batch`` every step); the deterministic policy then runs ``--episodes`` episodes (seeds 10,000 + i) and the info
of each terminating step gives the relative error (``relative_error``: NaN without an estimate). The atlas ids are
the training ids (PlateRotationAtlas-v0 for v0's point mass, PlateRotationAtlas-v1 for v1's faithful physics); the
live ids run at 12 (v0) and 0.6 (v1) steps/s here (``experiments/results/env_ids_speed.md``), so ``--live-steps``
only checks that tianshou collects and trains on them.

Writes ``experiments/results/tianshou_ppo.{json,md}`` (``--name``: another stem; ``tianshou_ppo_live_v0`` holds
``--ids PlateRotation-v0 --live`` , 20k steps on the live point mass).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import plate_env  # noqa: F401  (registers the ids)

RESULTS = Path(__file__).parent / "results"


def _policy(env: gym.Env, seed: int):
    import torch
    from tianshou.algorithm import PPO
    from tianshou.algorithm.modelfree.reinforce import ProbabilisticActorPolicy
    from tianshou.algorithm.optim import AdamOptimizerFactory
    from tianshou.utils.net.common import ActorCritic, Net
    from tianshou.utils.net.continuous import ContinuousActorProbabilistic, ContinuousCritic
    from torch.distributions import Independent, Normal

    torch.manual_seed(seed)
    obs_dim = env.observation_space.shape
    actor = ContinuousActorProbabilistic(preprocess_net=Net(state_shape=obs_dim, hidden_sizes=(64, 64)),
                                         action_shape=env.action_space.shape, unbounded=True)
    critic = ContinuousCritic(preprocess_net=Net(state_shape=obs_dim, hidden_sizes=(64, 64)))
    ActorCritic(actor, critic)

    def dist(loc_scale):
        loc, scale = loc_scale
        return Independent(Normal(loc, scale), 1)

    policy = ProbabilisticActorPolicy(actor=actor, dist_fn=dist, deterministic_eval=True,
                                      action_space=env.action_space, observation_space=env.observation_space,
                                      action_bound_method="clip")
    return PPO(policy=policy, critic=critic, optim=AdamOptimizerFactory(lr=3e-4)), policy


def train_and_score(env_id: str, steps: int, episodes: int, seed: int, n_envs: int = 4) -> dict:
    """Train tianshou PPO for ``steps`` env steps on ``env_id`` and score ``episodes`` deterministic episodes."""
    import torch
    from tianshou.data import Collector, VectorReplayBuffer
    from tianshou.env import DummyVectorEnv
    from tianshou.trainer import OnPolicyTrainerParams

    torch.set_num_threads(1)
    envs = DummyVectorEnv([lambda: gym.make(env_id) for _ in range(n_envs)])
    envs.seed([seed + i for i in range(n_envs)])
    algo, policy = _policy(gym.make(env_id), seed)
    collect = min(2048, steps)
    collector = Collector(algo, envs, VectorReplayBuffer(collect, n_envs))
    t0 = time.perf_counter()
    stats = algo.run_training(OnPolicyTrainerParams(
        training_collector=collector, max_epochs=1, epoch_num_steps=steps, collection_step_num_env_steps=collect,
        update_step_num_repetitions=10, batch_size=64, test_collector=None, test_step_num_episodes=0,
        test_in_training=False))
    train_s = time.perf_counter() - t0
    envs.close()
    info_keys_seen = sorted(collector.buffer.info.keys())
    policy.eval()
    errors, rewards, probes = [], [], []
    env = gym.make(env_id)
    t1 = time.perf_counter()
    for i in range(episodes):
        obs, info = env.reset(seed=10_000 + i)
        done, total = False, 0.0
        while not done:
            with torch.no_grad():
                from tianshou.data import Batch

                act = policy(Batch(obs=obs[None], info=Batch())).act[0]
            act = policy.map_action(np.asarray(act))
            obs, r, term, trunc, info = env.step(np.asarray(act, dtype=np.float32))
            total += r
            done = term or trunc
        errors.append(float(info["relative_error"]))
        rewards.append(total)
        probes.append(int(info["probes"]))
    eval_s = time.perf_counter() - t1
    env.close()
    err = np.array(errors)
    ok = np.isfinite(err)  # inf: no estimate
    return {"env_id": env_id, "train_steps": int(stats.update_collection_stat.n_collected_steps
                                                  if hasattr(stats, "update_collection_stat") else steps),
            "train_s": train_s, "steps_per_s": steps / train_s, "eval_episodes": episodes, "eval_s": eval_s,
            "median_error": float(np.median(err[ok])) if ok.any() else math.nan,
            "p90_error": float(np.quantile(err[ok], 0.9)) if ok.any() else math.nan,
            "no_estimate": float(1 - ok.mean()), "mean_reward": float(np.mean(rewards)),
            "median_probes": float(np.median(probes)), "buffer_info_keys": info_keys_seen}


def live_check(env_id: str, steps: int, seed: int) -> dict:
    """tianshou collects and trains ``steps`` steps on a live id (a smoke check of the client on the slow physics)."""
    import torch
    from tianshou.data import Collector, VectorReplayBuffer
    from tianshou.env import DummyVectorEnv
    from tianshou.trainer import OnPolicyTrainerParams

    torch.set_num_threads(1)
    envs = DummyVectorEnv([lambda: gym.make(env_id) for _ in range(2)])
    envs.seed([seed, seed + 1])
    algo, _ = _policy(gym.make(env_id), seed)
    collector = Collector(algo, envs, VectorReplayBuffer(steps, 2))
    t0 = time.perf_counter()
    algo.run_training(OnPolicyTrainerParams(
        training_collector=collector, max_epochs=1, epoch_num_steps=steps, collection_step_num_env_steps=steps,
        update_step_num_repetitions=2, batch_size=64, test_collector=None, test_step_num_episodes=0,
        test_in_training=False))
    envs.close()
    return {"env_id": env_id, "steps": steps, "seconds": time.perf_counter() - t0}


def _md(rec: dict) -> str:
    lines = ["# tianshou PPO on the env ids, no wrapper (issue 38)", "",
             f"Command: `{rec['command']}` at commit {rec['commit']}, tianshou {rec['tianshou']}, one run on "
             f"{rec['machine']} (load {rec['load']}).", "",
             "| id | train steps | train s | steps/s | episodes | median error | p90 | no estimate | mean reward | "
             "median probes |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rec["trained"]:
        lines.append(f"| {r['env_id']} | {r['train_steps']} | {r['train_s']:.0f} | {r['steps_per_s']:.0f} | "
                     f"{r['eval_episodes']} | {100 * r['median_error']:.1f} % | {100 * r['p90_error']:.1f} % | "
                     f"{100 * r['no_estimate']:.0f} % | {r['mean_reward']:.3f} | {r['median_probes']:.0f} |")
    if rec["live"]:
        lines += ["", "Live ids (collect and train only; too slow for 20k steps here):", "",
                  "| id | steps | seconds |", "|---|---|---|"]
        lines += [f"| {r['env_id']} | {r['steps']} | {r['seconds']:.0f} |" for r in rec["live"]]
    keys = rec["trained"][0]["buffer_info_keys"] if rec["trained"] else []
    lines += ["", f"Info keys tianshou stacked into its buffer every step: {', '.join(f'`{k}`' for k in keys)}."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ids", nargs="+", default=["PlateRotationAtlas-v0", "PlateRotationAtlas-v1"])
    ap.add_argument("--steps", type=int, default=20_000)
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--live", nargs="*", default=["PlateRotation-v0", "PlateRotation-v1"])
    ap.add_argument("--live-steps", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--name", default="tianshou_ppo", help="results file stem in experiments/results")
    args = ap.parse_args(argv)
    import os

    import tianshou

    trained = []
    for env_id in args.ids:
        trained.append(train_and_score(env_id, args.steps, args.episodes, args.seed))
        print(json.dumps({k: v for k, v in trained[-1].items() if k != "buffer_info_keys"}), flush=True)
    live = []
    for env_id in args.live:
        live.append(live_check(env_id, args.live_steps, args.seed))
        print(json.dumps(live[-1]), flush=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    rec = {"command": " ".join(["python experiments/tianshou_ppo.py", *(sys.argv[1:] if argv is None else argv)]),
           "commit": commit,
           "tianshou": tianshou.__version__, "machine": f"{platform.machine()}, {os.cpu_count()} cores",
           "load": f"{os.getloadavg()[0]:.1f}", "trained": trained, "live": live}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(rec, indent=1) + "\n")
    (RESULTS / f"{args.name}.md").write_text(_md(rec))
    print(_md(rec))


if __name__ == "__main__":
    main()
