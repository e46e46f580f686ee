"""rl-zoo3 with the shipped conf for PPO, SAC, TD3 and A2C on the training id (issue 41 item 3; issue 38 item 4).

    pip install -c constraints.txt -e ".[rl]" rl_zoo3
    python experiments/zoo_algos.py [--steps 20000] [--episodes 100] [--algos ppo,sac,td3,a2c] [--keep DIR]
        [--env PlateRotationAtlas-v1]

For each algorithm: ``python -m rl_zoo3.train --algo ALGO --env PlateRotationAtlas-v0 --gym-packages plate_env
--conf-file plate_env_agents.zoo --seed 0 --num-threads 1 -n STEPS --eval-freq -1`` in a fresh directory (wall
seconds of the whole command, the load before/after), then the saved zip is loaded through ``sb3:ALGO:zip``
(plate_env_agents.sb3_zip: nothing unpickled) and played deterministically on ``--episodes`` objects (env seeds
100000 + i) of PlateRotationAtlas-v0 with the entry's env_kwargs: the median relative error of omega_n, the share
of episodes with an estimate and the mean probes. ``--env``: another training id with entries in the shipped
conf (PlateRotationAtlas-v1 for SAC and TD3: the faithful atlas), trained and scored on it instead. ``--keep DIR``
keeps the zips (DIR/ALGO.zip) for ``plate-env bench --agent sb3:ALGO:DIR/ALGO.zip``. ``--score ALGO=ZIP ...``
only scores zips trained by that command elsewhere (e.g. stopped with Ctrl-C on a loaded machine: rl-zoo3 then
saves the model at the steps reached; the row's steps are the zip's ``num_timesteps`` and its wall time is not
measured here). Writes experiments/results/zoo_algos.json and .md (``--out``: another stem, for algorithms run as
separate invocations at once; ``--merge STEM ...`` then writes zoo_algos.json and .md from their runs, in the order
given; ``--rescore STEM``: score STEM's zips again, keeping their training fields). Before scoring, a zip without
a JSON sidecar gets one with the entry's env_kwargs: the ``sb3:`` agent reads the zip's training settings there.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).parent / "results"
ENV_ID = "PlateRotationAtlas-v0"


def load() -> float:
    return round(os.getloadavg()[0], 2)


def train(algo: str, steps: int, keep: Path | None, env_id: str = ENV_ID) -> dict:
    """One rl-zoo3 run in a fresh directory; the zip copied to ``keep`` (or a temporary file) for scoring."""
    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", algo, "--env", env_id, "--gym-packages", "plate_env",
           "--conf-file", "plate_env_agents.zoo", "--seed", "0", "--num-threads", "1", "-n", str(steps),
           "--eval-freq", "-1"]
    with tempfile.TemporaryDirectory() as tmp:
        before = load()
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp)
        wall = time.perf_counter() - t0
        if done.returncode != 0:
            raise SystemExit(f"rl_zoo3.train --algo {algo} failed:\n{done.stderr[-3000:]}")
        src = Path(tmp) / "logs" / algo / f"{env_id}_1" / f"{env_id}.zip"
        dest = (keep or Path(tempfile.mkdtemp())) / f"{algo}.zip"
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dest)
    return {"algo": algo, "command": " ".join(["python", *cmd[1:]]), "wall_s": round(wall, 1), "steps": steps,
            "load_before": before, "load_after": load(), "zip": str(dest)}


def score(algo: str, zip_path: str, episodes: int, env_id: str = ENV_ID) -> dict:
    """The deterministic policy on ``episodes`` seeded objects of the training id with the entry's env_kwargs."""
    import gymnasium as gym

    import plate_env  # noqa: F401 - registers the ids
    from plate_env.env.episode import run_episode
    from plate_env_agents import load_agent
    from plate_env_agents.zoo import hyperparams_of

    env_kwargs = hyperparams_of(algo)[env_id].get("env_kwargs", {})
    side = Path(zip_path).with_suffix(".json")
    if not side.exists():  # the sb3 agent reads the zip's training settings (band, amplitudes, windows) from here;
        # without it, PlateRotation-v0's: a v1 zip (3 and 6 deg) would see 6 deg encoded as v0's 12
        side.write_text(json.dumps({"env_id": env_id, "env_kwargs": env_kwargs}, indent=1) + "\n")
    agent = load_agent(f"sb3:{algo}:{zip_path}")
    env = gym.make(env_id, **env_kwargs)
    errs, probes, ok = [], [], []
    for i in range(episodes):
        res = run_episode(env, agent, seed=100_000 + i)
        ok.append(bool(res.estimate.ok))
        errs.append(res.relative_error if res.estimate.ok else np.inf)
        probes.append(res.n_probes)
    env.close()
    errs_a = np.asarray(errs)
    from plate_env_agents.sb3_zip import read_data

    return {"steps_trained": int(read_data(zip_path)["num_timesteps"]), "episodes": episodes,
            "median_rel_error": float(np.median(errs_a)),
            "p90_rel_error": float(np.quantile(errs_a, 0.9, method="higher")),  # inf: > 10 % without estimate
            "with_estimate": float(np.mean(ok)),
            "mean_probes": float(np.mean(probes))}


def _pct(x: float) -> str:
    """A relative error in percent; inf: no estimate; NaN: not available (a p90 before the fix to inf)."""
    return "inf (no estimate)" if x == np.inf else "n/a" if np.isnan(x) else f"{100 * x:.1f} %"


def write_md(r: dict, stem: str = "zoo_algos") -> None:
    env_id = r.get("env_id", ENV_ID)
    algos = ", ".join(dict.fromkeys(x["algo"].upper() for x in r["runs"]))
    env_opt = f" --env {env_id}" if env_id != ENV_ID else ""
    at = "the commits in the table" if r.get("merged_from") else f"commit `{r['commit']}`"
    lines = [f"# rl-zoo3 with the shipped conf: {algos} on {env_id}", "",
             f"`python experiments/zoo_algos.py --steps {r['steps']} --episodes {r['episodes']}{env_opt}` at "
             f"{at}, rl_zoo3 {r['rl_zoo3']}, stable-baselines3 {r['sb3']}, torch {r['torch']}; 2 shared "
             "cores (load average before / after each training). Each row: `python -m rl_zoo3.train --algo ALGO "
             f"--env {env_id} --gym-packages plate_env --conf-file plate_env_agents.zoo --seed 0 --num-threads 1 "
             f"-n {r['steps']} --eval-freq -1` (wall seconds of the whole command), then the saved zip loaded "
             "through `sb3:ALGO:zip` and played deterministically on the same "
             f"{r['episodes']} seeded objects (env seeds 100000+i, the entry's env_kwargs). Relative error of "
             "omega_n; an episode without an estimate counts as an infinite error. PPO: its tuned entry "
             "(agents/hyperparams/ppo.yml) cut to the same steps; SAC, TD3, A2C: SB3's defaults (their files).", "",
             *([f"Merged from {', '.join(r['merged_from'])} (`--merge`): separate invocations (the commit column), "
                "some partly at the same time on the same cores as other jobs, so wall times are comparable only "
                "with the load beside them.", ""] if r.get("merged_from") else []),
             *([f"Rescored (`--rescore`): {', '.join(x['algo'] for x in r['runs'] if x.get('rescored'))}, their zips "
                "played again after their training (the training columns are the first run's)"
                + (f": {r['rescore_reason']}" if r.get("rescore_reason") else "") + ".", ""]
               if any(x.get("rescored") for x in r["runs"]) else []),
             "| algorithm | commit | steps trained | train wall s | load before / after | median rel. error | "
             "90th pct | with estimate | mean probes |", "|---|---|---|---|---|---|---|---|---|"]
    for x in r["runs"]:
        wall = f"{x['wall_s']:.0f}" if x.get("wall_s") is not None else "not measured (--score)"
        lines.append(f"| {x['algo']} | {x.get('commit', r['commit'])} | {x.get('steps_trained', x.get('steps'))} | "
                     f"{wall} | "
                     f"{x.get('load_before', '-')} / {x.get('load_after', '-')} | "
                     f"{_pct(x['median_rel_error'])} | {_pct(x['p90_rel_error'])} | "
                     f"{100 * x['with_estimate']:.0f} % | {x['mean_probes']:.1f} |")
    (RESULTS / f"{stem}.md").write_text("\n".join(lines) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20_000)
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--algos", default="ppo,sac,td3,a2c")
    ap.add_argument("--env", default=ENV_ID, help="the training id (its entries in the shipped conf)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the trained zips in this folder")
    ap.add_argument("--out", default="zoo_algos", help="stem of the result files in experiments/results")
    ap.add_argument("--merge", nargs="+", default=None, help="only merge these result stems into zoo_algos")
    ap.add_argument("--score", nargs="+", default=None, metavar="ALGO=ZIP", help="only score these zips")
    ap.add_argument("--rescore", default=None, metavar="STEM",
                    help="score the zips of STEM.json's runs again, keeping their training fields")
    args = ap.parse_args()
    if args.rescore:
        doc = json.loads((RESULTS / f"{args.rescore}.json").read_text())
        for run in doc["runs"]:
            run.update(score(run["algo"], run["zip"], doc["episodes"], doc.get("env_id", ENV_ID)), rescored=True)
            print(json.dumps(run), flush=True)
        (RESULTS / f"{args.rescore}.json").write_text(json.dumps(doc, indent=1) + "\n")
        write_md(doc, args.rescore)
        return
    if args.merge:
        parts = [json.loads((RESULTS / f"{stem}.json").read_text()) for stem in args.merge]
        out = {**parts[0], "runs": [{"commit": part["commit"], **run} for part in parts for run in part["runs"]],
               "merged_from": args.merge}
        (RESULTS / f"{args.out}.json").write_text(json.dumps(out, indent=1) + "\n")
        write_md(out, args.out)
        return
    import rl_zoo3
    import stable_baselines3
    import torch

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=Path(__file__).parent).stdout.strip()
    out = {"steps": args.steps, "episodes": args.episodes, "commit": commit, "rl_zoo3": rl_zoo3.__version__,
           "sb3": stable_baselines3.__version__, "torch": torch.__version__, "env_id": args.env, "runs": []}
    jobs = [tuple(x.split("=", 1)) for x in args.score] if args.score else [(a, None) for a in args.algos.split(",")]
    for algo, zip_path in jobs:
        run = train(algo, args.steps, args.keep, args.env) if zip_path is None else {"algo": algo, "zip": zip_path,
                                                                           "wall_s": None}
        run.update(score(algo, run["zip"], args.episodes, args.env))
        out["runs"].append(run)
        print(json.dumps(run), flush=True)
        (RESULTS / f"{args.out}.json").write_text(json.dumps(out, indent=1) + "\n")
        write_md(out, args.out)


if __name__ == "__main__":
    main()
