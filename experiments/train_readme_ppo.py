"""The README's Stable-Baselines3 snippet, run as it stands, timed: PPO with SB3's defaults on the SB3 vector env.

    python experiments/train_readme_ppo.py [--timesteps 100000] [--out experiments/results/models/readme_ppo.zip]

Writes the model and, beside it, a JSON with the steps, wall seconds, load average and versions. The leaderboard
(``plate-env bench --agent ... sb3:<model>``) evaluates it beside the shipped agents.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--timesteps", type=int, default=100_000)
    ap.add_argument("--out", type=Path, default=Path("experiments/results/models/readme_ppo.zip"))
    args = ap.parse_args()
    import stable_baselines3
    import torch

    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    # --- the README's snippet ---
    from stable_baselines3 import PPO

    from plate_env.env.sb3 import make_sb3_vec_env

    torch.set_num_threads(1)
    model = PPO("MlpPolicy", make_sb3_vec_env(n_envs=8, physics="atlas", seed=0), seed=0, device="cpu", verbose=1)
    model.learn(args.timesteps)
    model.save(args.out)
    # ---
    wall = time.perf_counter() - t0
    info = {"snippet": "PPO('MlpPolicy', make_sb3_vec_env(n_envs=8, physics='atlas', seed=0), seed=0, device='cpu', "
                       "verbose=1)"
                       f".learn({args.timesteps})", "timesteps": int(model.num_timesteps), "wall_s": round(wall, 1),
            "load_avg_start": load0, "load_avg_end": os.getloadavg()[0], "torch_threads": 1,
            "versions": {"python": platform.python_version(), "stable_baselines3": stable_baselines3.__version__,
                         "torch": torch.__version__}}
    args.out.with_suffix(".json").write_text(json.dumps(info, indent=1) + "\n")
    print(json.dumps(info))


if __name__ == "__main__":
    main()
