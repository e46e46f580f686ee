"""Steps per second of each registered id with random actions (issue 41: which id is for training).

    python experiments/env_ids_speed.py [--steps 300]

One run; prints medians over episodes and the ratio of each id to PlateRotation-v0, and writes
experiments/results/env_ids_speed.md.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import plate_env


def steps_per_second(env_id: str, steps: int, seed: int = 0) -> tuple[float, int]:
    """Median steps/s over episodes of random actions (the stop bit off so episodes run their probe budget)."""
    env = gym.make(env_id)
    rng = np.random.default_rng(seed)
    rates, done_steps, ep = [], 0, 0
    while done_steps < steps:
        env.reset(seed=seed + ep)
        ep += 1
        t0, n, term = time.perf_counter(), 0, False
        while not term and done_steps < steps:
            a = rng.uniform(-1, 1, 4).astype(np.float32)
            a[3] = -1.0
            *_, term, _, _ = env.step(a)
            n += 1
            done_steps += 1
        rates.append(n / (time.perf_counter() - t0))
    env.close()
    return float(np.median(rates)), done_steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=300)
    args = ap.parse_args()
    ids = sorted(plate_env.ENV_IDS)
    rows = {i: steps_per_second(i, args.steps if "Atlas" in i else max(args.steps // 10, 30)) for i in ids}
    base = rows["PlateRotation-v0"][0]
    load = os.getloadavg()[0]
    lines = ["# Steps per second of each registered id", "",
             f"`python experiments/env_ids_speed.py --steps {args.steps}`: random actions (no stop), median over "
             f"episodes, one run at load {load:.1f} on this machine (live ids get a tenth of the steps).", "",
             "| id | physics | steps | median steps/s | x PlateRotation-v0 |", "|---|---|---|---|---|"]
    for i, (rate, n) in rows.items():
        kw = plate_env.ENV_IDS[i]
        what = kw.get("physics", "tilelink") + (f" ({kw['physics_options']['model']})" if "physics_options" in kw
                                                else " (pointmass)")
        lines.append(f"| `{i}` | {what} | {n} | {rate:.1f} | {rate / base:.2f} |")
    text = "\n".join(lines) + "\n"
    (Path(__file__).parent / "results" / "env_ids_speed.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
