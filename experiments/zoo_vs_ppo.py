"""SAC and TD3 at SB3's defaults (20,000 steps, rl-zoo3 with the shipped conf) against the shipped PPO on the two
leaderboards' suites, paired on the same episodes (issue 38: "a leaderboard row for off-the-shelf learners beside
the shipped PPO"):

    python experiments/zoo_vs_ppo.py

Reads the episodes the leaderboards' ``plate-env bench`` runs kept in ``.plate_env_bench/<suite>.jsonl`` (run the
boards' Regenerate commands first, from the repository's root; an agent not in the cache is played here). For each
suite and each pair (SAC or TD3, a shipped PPO): the median over objects of the capped-error difference, agent - PPO,
in percentage points with its 95 % bootstrap interval, at each of the suite's budgets
(:func:`plate_env.bench.summary.compare`, the boards' own paired statistic; negative: the off-the-shelf learner is
the more accurate). Writes experiments/results/zoo_vs_ppo.json and .md.
"""

from __future__ import annotations

import json
from pathlib import Path

RESULTS = Path(__file__).parent / "results"
MODELS = "experiments/results/models"
#: suite -> (its off-the-shelf zips, the shipped PPOs on its board)
PAIRS = {
    "atlas-v0": ([f"sb3:sac:{MODELS}/sac_atlas.zip", f"sb3:td3:{MODELS}/td3_atlas.zip"], ["ppo"]),
    "faithful-v0": ([f"sb3:sac:{MODELS}/sac_faithful.zip", f"sb3:td3:{MODELS}/td3_faithful.zip"],
                    ["ppo:path=agents/models/ppo_faithful.zip", "ppo"]),
}


def main() -> None:
    from plate_env import bench
    from plate_env.bench.suites import load_suite
    from plate_env.bench.summary import compare
    from plate_env_agents import load_agent

    out = {}
    for name, (zoo, ppos) in PAIRS.items():
        suite = load_suite(name)
        cache = Path(".plate_env_bench") / f"{name}.jsonl"
        runs = {spec: bench.evaluate(load_agent(spec), suite, label=spec, cache=cache) for spec in [*zoo, *ppos]}
        out[name] = {a: {p: {f"{b:g}": compare(runs[a], runs[p], b).to_dict() for b in suite.budgets_s}
                         for p in ppos} for a in zoo}
    (RESULTS / "zoo_vs_ppo.json").write_text(json.dumps(out, indent=1) + "\n")
    lines = ["# SAC and TD3 at SB3's defaults against the shipped PPO, paired on the same episodes", "",
             "`python experiments/zoo_vs_ppo.py`: median over the suite's 100 objects of (agent's error - PPO's "
             "error), errors capped at 100 %, in percentage points with 95 % bootstrap intervals (the leaderboards' "
             "paired statistic); negative: the off-the-shelf learner is the more accurate. The zips "
             "(slim: data and actor, experiments/zoo_slim.py) and their sidecars: "
             "experiments/results/models/{sac,td3}_{atlas,faithful}.{zip,json}.", ""]
    for name, per in out.items():
        budgets = list(next(iter(next(iter(per.values())).values())))
        lines += [f"## {name}", "", "| agent - PPO | " + " | ".join(f"@ {b} s" for b in budgets) + " |",
                  "|---|" + "---|" * len(budgets)]
        for a, vs in per.items():
            for p, cells in vs.items():
                stats = [f"{100 * c['value']:.1f} [{100 * c['ci95'][0]:.1f}, {100 * c['ci95'][1]:.1f}]"
                         for c in cells.values()]
                lines.append(f"| `{a}` - `{p}` | " + " | ".join(stats) + " |")
        lines.append("")
    (RESULTS / "zoo_vs_ppo.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
