"""How long rl-zoo3 takes to train PPO on PlateRotation-v0 with the installed hyperparameters (issue 25).

    pip install -c constraints.txt -e ".[rl]" rl_zoo3
    python experiments/zoo_timing.py [--steps 16384] [--skip-full]

Runs the README's command, ``python -m rl_zoo3.train --algo ppo --env PlateRotation-v0 --gym-packages plate_env
--conf-file plate_env_agents.zoo --seed 0``, in a fresh temporary directory, as a user would:

1. with ``--num-threads 1`` for the file's whole ``n_timesteps`` (rl-zoo3's own evaluations included): the wall
   seconds of the whole command, what the issue's "200k steps in <= 5 min on 2 cores" is about;
2. with and without ``--num-threads 1`` for ``--steps`` steps and no evaluation (``--eval-freq -1``), one after the
   other: torch's default on this machine is one thread per core, and the env runs on the same cores.

Steps are rl-zoo3's last logged ``total_timesteps``; the load (``os.getloadavg``) is recorded before and after each
run. Writes experiments/results/zoo_timing.json (the source) and .md (generated from it; ``--md`` rewrites it).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import commit, load

RESULTS = Path(__file__).parent / "results"
COMMAND = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "PlateRotation-v0", "--gym-packages",
           "plate_env", "--conf-file", "plate_env_agents.zoo", "--seed", "0"]


def run(extra: list[str]) -> dict:
    """One rl-zoo3 training run in a fresh directory: wall seconds, steps run, load before/after."""
    with tempfile.TemporaryDirectory() as tmp:
        before = load()
        t0 = time.perf_counter()
        done = subprocess.run([*COMMAND, *extra], capture_output=True, text=True, cwd=tmp)
        wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"rl_zoo3.train {' '.join(extra)} failed:\n{done.stderr[-2000:]}")
    steps = [int(m) for m in re.findall(r"total_timesteps\s*\|\s*(\d+)", done.stdout)]
    evals = len(re.findall(r"Eval num_timesteps=", done.stdout))
    return {"args": extra, "wall_s": wall, "steps": steps[-1] if steps else None, "evaluations": evals,
            "load_before": before, "load_after": load()}


def write_md(r: dict) -> None:
    lines = ["# rl-zoo3 PPO on PlateRotation-v0 with the installed hyperparameters", "",
             f"`{r['command']}` at commit `{r['commit']}`, rl_zoo3 {r['rl_zoo3']}, torch {r['torch']}; 2 cores, "
             "shared (load average before / after each run). The command: `" + " ".join(
                 ["python", *COMMAND[1:]]) + "` plus the arguments shown, in a fresh directory.", "",
             "| arguments | steps | evaluations | wall s | steps/s (whole command) | load before / after |",
             "|---|---|---|---|---|---|"]
    for x in r["runs"]:
        rate = f"{x['steps'] / x['wall_s']:.0f}" if x["steps"] else "n/a"
        lines.append(f"| `{' '.join(x['args']) or '(none)'}` | {x['steps']:,} | {x['evaluations']} | "
                     f"{x['wall_s']:.1f} | {rate} | {x['load_before'][0]} / {x['load_after'][0]} |")
    lines += ["", "The steps/s include start-up (imports, env and model construction) and rl-zoo3's evaluations."]
    (RESULTS / "zoo_timing.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=16384, help="steps of the two short runs (default 16384)")
    ap.add_argument("--skip-full", action="store_true", help="only the two short runs")
    ap.add_argument("--md", action="store_true", help="only rewrite the .md from the .json")
    args = ap.parse_args()
    if args.md:
        write_md(json.loads((RESULTS / "zoo_timing.json").read_text()))
        return
    try:
        import rl_zoo3
        import torch
    except ImportError as exc:
        raise SystemExit(f"{exc}: install rl-zoo3 first (pip install -c constraints.txt -e '.[rl]' rl_zoo3)") from None
    runs = []
    if not args.skip_full:
        runs.append(run(["--num-threads", "1"]))
        print(runs[-1], flush=True)
    for extra in (["--num-threads", "1"], []):
        runs.append(run(["-n", str(args.steps), "--eval-freq", "-1", *extra]))
        print(runs[-1], flush=True)
    r = {"command": " ".join(["python experiments/zoo_timing.py", *sys.argv[1:]]), "commit": commit(),
         "rl_zoo3": rl_zoo3.__version__, "torch": torch.__version__, "runs": runs}
    (RESULTS / "zoo_timing.json").write_text(json.dumps(r, indent=1) + "\n")
    write_md(r)


if __name__ == "__main__":
    main()
