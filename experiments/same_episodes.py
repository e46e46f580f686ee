"""Seeded episodes give the same numbers on this tree and on a reference commit (bit for bit).

    python experiments/same_episodes.py --ref 284a76f [--episodes 5]

In a fresh process per tree (as experiments/bench_speed.py runs them): the atlas env stepped with seeded random
actions (every observation, reward, termination and info, the episode-end estimate included), and the grid and
bayes agents' episodes through ``run_episode`` (estimate and probes). Prints "identical" and exits 0, or the first
differences and exits 1. The benchmark's scores are compared with ``plate-env bench ... --json`` and
experiments/same_numbers.py.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from common import attr, diffs, overlay, tree_path


def episodes(n: int) -> dict:
    import numpy as np

    from plate_env.env import PlateRotationEnv
    from plate_env_agents import make_agent

    run_episode = attr("plate_env.env.episode", "plate_env.episode", "run_episode")

    def clean(x):
        return json.loads(json.dumps(x, default=lambda o: o.tolist() if hasattr(o, "tolist") else repr(o)))

    out: dict = {"env": [], "agents": {}}
    env = PlateRotationEnv(physics="atlas")
    rng = np.random.default_rng(0)
    for seed in range(n):
        obs, info = env.reset(seed=seed)
        steps = [clean({"obs": obs, "info": info})]
        done = False
        while not done:
            a = rng.uniform(-1, 1, 4).astype(np.float32)
            a[3] = 1.0 if rng.uniform() < 0.15 else -1.0
            obs, r, term, trunc, info = env.step(a)
            info.pop("wall_s", None)  # wall-clock seconds differ between runs by nature
            steps.append(clean({"obs": obs, "reward": r, "term": term, "trunc": trunc, "info": info}))
            done = term or trunc
        out["env"].append(steps)
    for name in ("grid", "bayes"):
        res = [run_episode(env, make_agent(name), seed=seed) for seed in range(min(n, 3))]
        out["agents"][name] = [clean({"estimate": r.estimate.to_dict(), "probes": r.probes.to_rows(),
                                      "sim_s": r.sim_s}) for r in res]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", default=None)
    ap.add_argument("--episodes", type=int, default=5)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(episodes(args.episodes)))
        return
    if not args.ref:
        ap.error("--ref REV: the commit to compare with")
    runs = []
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        for ref in (args.ref, None):
            path = overlay(tree_path(ref, tmp), tmp)
            done = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child", "--episodes",
                                   str(args.episodes)], capture_output=True, text=True, check=True,
                                  env=dict(os.environ, PYTHONPATH=str(path)), cwd=tempfile.gettempdir())
            runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    found = diffs(*runs)
    n_steps = sum(len(e) for e in runs[0]["env"])
    print("identical" if not found else "\n".join(found[:20]),
          f"({len(runs[0]['env'])} env episodes, {n_steps} steps; grid and bayes episodes)")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
