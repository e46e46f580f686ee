"""Environment throughput per physics: env steps per second and simulated seconds per wall second.

    python experiments/bench_env.py [--steps 40] [--num-envs 8] [--pybullet-steps 4]

Single env (`gym.make`) and vector env (`gym.make_vec(..., vectorization_mode="vector_entry_point")`, one
batched physics call per step) with random probe actions; medians over repeats measured in this one run.
Writes experiments/results/bench_env.md.
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import numpy as np

import plate_env  # noqa: F401 - registers the env


def random_actions(rng, n, shape):
    a = rng.uniform(-1, 1, (n, *shape)).astype(np.float32)
    a[..., 3] = -1.0
    return a


def bench_single(physics: str, steps: int, repeats: int, **kw) -> tuple[float, float]:
    env = gym.make("PlateRotation-v0", physics=physics, max_probes=200, **kw)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    env.step(random_actions(rng, 1, (4,))[0])  # warm up (kernel cache)
    rates, rtfs = [], []
    for _ in range(repeats):
        acts = random_actions(rng, steps, (4,))
        t0 = time.perf_counter()
        for a in acts:
            _, _, _, _, info = env.step(a)
        wall = time.perf_counter() - t0
        rates.append(steps / wall)
        rtfs.append(info["sim_s"] / wall)
        env.reset(seed=1)
    env.close()
    return statistics.median(rates), statistics.median(rtfs)


def bench_vector(physics: str, steps: int, num_envs: int, repeats: int, mode: str) -> tuple[float, float]:
    env = gym.make_vec("PlateRotation-v0", num_envs=num_envs, vectorization_mode=mode, physics=physics,
                       max_probes=200)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    env.step(random_actions(rng, num_envs, (4,)))
    rates, rtfs = [], []
    for r in range(repeats):
        env.reset(seed=r + 1)
        t0 = time.perf_counter()
        for a in random_actions(rng, steps, (num_envs, 4)):
            _, _, _, _, info = env.step(a)
        wall = time.perf_counter() - t0
        rates.append(steps * num_envs / wall)
        rtfs.append(float(np.sum(info["sim_s"])) / wall)
    env.close()
    return statistics.median(rates), statistics.median(rtfs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--num-envs", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--pybullet-steps", type=int, default=3, help="0 to skip pybullet")
    args = ap.parse_args()
    lines = ["# PlateRotation-v0 throughput", "",
             f"Random probe actions (f_p 10-40 Hz, A_p 3/12 deg, windows 0.25-2 s), medians of {args.repeats} "
             "repeats in one run on a shared 2-core machine. Regenerate: `python experiments/bench_env.py`.", "",
             "| physics | env | env steps per wall s | simulated s per wall s |", "|---|---|---|---|"]
    for physics in ("atlas", "tilelink"):
        sps, rtf = bench_single(physics, args.steps, args.repeats)
        lines.append(f"| {physics} | single | {sps:.1f} | {rtf:.1f} |")
        print(lines[-1], flush=True)
        for mode in ("sync", "vector_entry_point"):
            sps, rtf = bench_vector(physics, args.steps, args.num_envs, args.repeats, mode)
            lines.append(f"| {physics} | vector x{args.num_envs} ({mode}) | {sps:.1f} | {rtf:.1f} |")
            print(lines[-1], flush=True)
    if args.pybullet_steps:
        sps, rtf = bench_single("pybullet", args.pybullet_steps, 1, method="lorentz")
        lines.append(f"| pybullet | single | {sps:.2f} | {rtf:.2f} |")
        print(lines[-1], flush=True)
    with open("experiments/results/bench_env.md", "w") as fh:
        fh.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
