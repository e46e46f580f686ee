"""The closing note of the benchmark (issue 14): experiments/results/benchmark_issue14.md/.json, read from the JSON
files the bench writes (AGENTS: the leaderboard's, as in docs/benchmark.md):

    plate-env bench --suite tilelink-v0 --agent AGENTS --markdown experiments/results/leaderboard_tilelink-v0.md \
        --plot experiments/results/leaderboard_tilelink-v0.png --json > experiments/results/leaderboard_tilelink-v0.json
    plate-env bench --suite tilelink-v0 --agent AGENTS --cache .plate_env_bench/tilelink-v0_process2.jsonl \
        --markdown experiments/results/leaderboard_tilelink-v0_process2.md \
        --json > experiments/results/leaderboard_tilelink-v0_process2.json       # a fresh process, its own cache
    plate-env bench --suite atlas-v0 --agent AGENTS --markdown experiments/results/leaderboard_atlas-v0.md \
        --plot experiments/results/leaderboard_atlas-v0.png --json > experiments/results/leaderboard_atlas-v0.json
    plate-env bench --suite tilelink-v0 --agent examples/sweep_agent.py:SweepAgent --no-cache --json \
        > experiments/results/bench_cli_tilelink-v0.json
    python experiments/train_readme_ppo.py

    python experiments/benchmark_report.py [--cli-wall-s S]     # S: the wall seconds of the --no-cache run, if timed
"""

from __future__ import annotations

import argparse
import json
import platform
import re
import subprocess
import sys
from pathlib import Path

R = Path("experiments/results")
BUDGETS = (10.0, 20.0, 40.0)
#: Run 2's own cache (a fresh process that reads nothing of run 1).
PROCESS2_CACHE = ".plate_env_bench/tilelink-v0_process2.jsonl"
HEAD1 = ("| agent | area (mean median error, 0-40 s) | median @ 10 s | median @ 20 s | median @ 40 s | p90 @ 40 s "
         "| no estimate @ 40 s | coverage 68 % / 95 % @ 40 s | probes @ 40 s | wall s per decision, run 1 / run 2 "
         "|\n|---|---|---|---|---|---|---|---|---|---|\n")
HEAD2 = ("| agent | median, atlas-v0 | median, tilelink-v0 | no estimate, atlas-v0 | no estimate, tilelink-v0 "
         "| probes, atlas | probes, live |\n|---|---|---|---|---|---|---|\n")


def st(s: dict, d: int = 1) -> str:
    """``value [lo, hi]`` in %; None is a non-finite number as the bench's JSON writes it (an infinite error)."""
    def num(x: float | None) -> str:
        return "inf" if x is None or x == float("inf") else f"{100 * x:.{d}f}"

    if num(s["value"]) == "inf":
        return "none"
    return f"{num(s['value'])} [{num(s['ci95'][0])}, {num(s['ci95'][1])}]"


def command_of(md: Path) -> str:
    """The ``plate-env bench`` command a leaderboard's markdown names in its "Regenerate:" line."""
    m = re.search(r"Regenerate: `([^`]+)`", md.read_text())
    if m is None:
        raise SystemExit(f"{md}: no 'Regenerate: `command`' line (write it with plate-env bench --markdown)")
    return m[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli-wall-s", type=float, default=None, help="wall seconds of the --no-cache plate-env bench run "
                    "(not in its JSON; left out of the note when not given)")
    ap.add_argument("--note", default="", help="a paragraph under the title (e.g. the commit the runs measured)")
    args = ap.parse_args()
    lb = json.loads((R / "leaderboard_tilelink-v0.json").read_text())
    lb2 = {a["label"]: a for a in json.loads((R / "leaderboard_tilelink-v0_process2.json").read_text())["agents"]}
    at = {a["label"]: a for a in json.loads((R / "leaderboard_atlas-v0.json").read_text())["agents"]}
    cli = json.loads((R / "bench_cli_tilelink-v0.json").read_text())
    rp = json.loads((R / "models/readme_ppo.json").read_text())
    sp = json.loads(Path("agents/models/ppo_plate.json").read_text())
    same = subprocess.run([sys.executable, "experiments/same_numbers.py", str(R / "leaderboard_tilelink-v0.json"),
                           str(R / "leaderboard_tilelink-v0_process2.json")], capture_output=True, text=True)
    walls = {a["label"]: [a["seconds_per_decision"]["value"], lb2[a["label"]]["seconds_per_decision"]["value"]]
             for a in lb["agents"]}
    rows, gap = [], []
    for a in lb["agents"]:
        b = {x["budget_s"]: x for x in a["budgets"]}
        top = b[BUDGETS[-1]]
        w = " / ".join(f"{x:.3g}" for x in walls[a["label"]])
        rows.append(f"| {a['label']} | {st(a['area'])} | " + " | ".join(st(b[x]["median_error"]) for x in BUDGETS)
                    + f" | {st(top['p90_error'])} | {st(top['no_estimate'])} | {st(top['coverage68'], 0)} / "
                    f"{st(top['coverage95'], 0)} | {top['probes_mean']:.1f} | {w} |")
        s = at[a["label"]]["budgets"][-1]
        gap.append(f"| {a['label']} | {st(s['median_error'])} | {st(top['median_error'])} | {st(s['no_estimate'])} | "
                   f"{st(top['no_estimate'])} | {s['probes_mean']:.1f} | {top['probes_mean']:.1f} |")
    cli_rows = {a["label"]: a for a in cli["agents"]}
    from common import diffs

    lb_rows = {a["label"]: a for a in lb["agents"]}
    cli_equal = {k: not diffs(v, lb_rows[k]) for k, v in cli_rows.items()}
    ex = next(a for a in cli["agents"] if a["label"].startswith("examples/"))
    eb = ex["budgets"]
    note = args.note + "\n\n" if args.note else ""
    python = lb.get("python") or platform.python_version()  # the bench's JSON does not record it: this process's
    lb_cmd, at_cmd = (command_of(R / f"leaderboard_{x}.md") for x in ("tilelink-v0", "atlas-v0"))
    lb2_cmd = f"{lb_cmd} --cache {PROCESS2_CACHE}"
    cli_wall = "" if args.cli_wall_s is None else f"{args.cli_wall_s:.0f} s of wall time for "
    md = f"""# Issue 14, closing measurements: the benchmark

{note}Regenerate: `python experiments/benchmark_report.py [--cli-wall-s S]` after the `plate-env bench` commands in
its docstring. A 2-core machine shared with other jobs (every job under `nice`), Python {python},
Stable-Baselines3 {rp['versions']['stable_baselines3']}, torch {rp['versions']['torch']} at one thread. Errors in %
with 95 % percentile-bootstrap intervals over the suite's objects.

## 1. Leaderboard on `tilelink-v0` (100 objects, live tile-link point-mass model; budgets 10, 20, 40 simulated s)

```bash
{lb_cmd}     # run 1
{lb2_cmd}     # run 2: a fresh process, its own empty cache
```

Full tables (every metric per budget, paired differences against the leader): `leaderboard_tilelink-v0.md/.json/.png`.

""" + HEAD1 + "\n".join(rows) + f"""

Both runs played every episode (each its own cache). `grid` is the paper's method (Lorentzian fit, Eq. 10) on
the 16-probe 10-40 Hz sweep at 3 deg; `grid:method=atlas` the same sweep read by the forward model's posterior.

## 2. The same numbers from two fresh processes

```bash
python experiments/same_numbers.py experiments/results/leaderboard_tilelink-v0.json \\
    experiments/results/leaderboard_tilelink-v0_process2.json
# {same.stdout.strip()}
```

Run 2 read nothing of run 1 (another cache file; it played every episode itself). A third fresh process, the command
line without a cache (section 4), gave rows {'equal to' if all(cli_equal.values()) else 'NOT equal to'} the
leaderboard's for the agents it ran, {', '.join(cli_rows)} (wall seconds per decision aside).

## 3. SB3 PPO trained from the README's snippet

`python experiments/train_readme_ppo.py` runs the README's snippet as it stands
(`{rp['snippet']}`): **{rp['timesteps']:,} steps** (`learn(100_000)` ends the rollout it is in: 7 x 8 envs x 2048)
in **{rp['wall_s']:.0f} s** of wall time at one torch thread, load average {rp['load_avg_start']:.1f} at the start
and {rp['load_avg_end']:.1f} at the end (`models/readme_ppo.json`). Evaluated by the bench beside the shipped agents
as `sb3:experiments/results/models/readme_ppo.zip`: its row above.

The shipped policy (`agents/models/ppo_plate.zip`) was retrained through the public API:
`{sp['command']}`, {sp['timesteps']:,} steps, {sp['n_envs']} envs, {sp['train_wall_s']:.0f} s of wall time at one
torch thread (hyperparameters `experiments/hyperparams/ppo.yml`; curve and versions in `agents/models/ppo_plate.json`).

## 4. The example third-party agent through `--agent file.py:Class`

```bash
plate-env bench --suite tilelink-v0 --agent examples/sweep_agent.py:SweepAgent --no-cache --json \\
    > experiments/results/bench_cli_tilelink-v0.json
```

{cli_wall}{100 * len(cli_rows)} episodes (`bench_cli_tilelink-v0.json/.md`). The example
agent (`examples/sweep_agent.py`, the README's ~20 lines: sweep up the band at 3 deg in 2 Hz steps, stop once the last
two probes fall below the highest response): area {st(ex['area'])}, median error {st(eb[0]['median_error'])} /
{st(eb[1]['median_error'])} / {st(eb[2]['median_error'])} at 10 / 20 / 40 s, p90 {st(eb[2]['p90_error'])} at 40 s,
no estimate {st(eb[2]['no_estimate'])}, {eb[2]['probes_mean']:.1f} probes on average.

## 5. Sim to live on the same objects: `atlas-v0` against `tilelink-v0` at 40 s

`{at_cmd}` (`leaderboard_atlas-v0.md/.json/.png`): the same 100 objects and
seeds, each probe answered by the tile-link atlas (the PPO policies were trained on the atlas).

""" + HEAD2 + "\n".join(gap) + "\n"
    (R / "benchmark_issue14.md").write_text(md)
    out = {"suite": lb["suite"], "suite_sha256": lb["suite_sha256"], "same_numbers": same.stdout.strip(),
           "same_numbers_exit": same.returncode, "wall_s_per_decision_run1_run2": walls,
           "cli": {"wall_s_both_agents": args.cli_wall_s, "rows_equal_to_leaderboard": cli_equal},
           "readme_ppo": rp, "shipped_ppo": {k: sp[k] for k in ("command", "timesteps", "n_envs", "train_wall_s",
                                                                 "seed", "date")},
           "files": ["leaderboard_tilelink-v0.json", "leaderboard_tilelink-v0_process2.json",
                     "leaderboard_atlas-v0.json", "bench_cli_tilelink-v0.json"]}
    (R / "benchmark_issue14.json").write_text(json.dumps(out, indent=1) + "\n")
    print(md)


if __name__ == "__main__":
    main()
