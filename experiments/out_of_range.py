"""Issue 37 item 1: objects outside the identifiable range on the live point mass, every shipped agent.

    python experiments/out_of_range.py [--agents coarse_to_fine,ppo,grid,bayes] [--omegas 0.3,0.5,1,50,60,100,200]
        [--seeds 0,1] [--jsonl episodes.jsonl]

One episode per (agent, omega_n, seed) on ``PlateRotation-v0`` with ``physics="tilelink"`` (alpha 45 deg), as
``plate-env identify --agent A --physics tilelink --omega-n Xpi --alpha 45 --seed S`` runs it. Counts per agent:
confident estimates (ok), those whose 95 % interval excludes the truth (wrong), bounds and bounds on the wrong side.
Prints a markdown table (experiments/results/estimate_contract.md, section 3).
"""

from __future__ import annotations

import argparse
import json
import math
import warnings


def episode(agent: str, omega_pi: float, seed: int) -> dict:
    import gymnasium as gym

    from plate_env.env.episode import run_episode
    from plate_env_agents import make_agent

    env = gym.make("PlateRotation-v0", physics="tilelink")
    try:
        e = run_episode(env, make_agent(agent), seed=seed, options={"omega_n": omega_pi * math.pi,
                                                                    "alpha": math.radians(45.0)}).estimate
    finally:
        env.close()
    truth = omega_pi * math.pi
    return {"agent": agent, "omega_pi": omega_pi, "seed": seed, "ok": e.ok, "estimate_pi": e.omega_n / math.pi,
            "ci95_pi": [x / math.pi for x in e.omega_n_ci95],
            "bound": None if e.bound is None else [e.bound[0], e.bound[1] / math.pi],
            "wrong": bool(e.ok and not e.omega_n_ci95[0] <= truth <= e.omega_n_ci95[1]),
            "bound_wrong": bool(e.bound is not None and (e.bound[0] == "above") != (truth > e.bound[1])),
            "reason": e.reason}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--agents", default="coarse_to_fine,ppo,grid,bayes")
    ap.add_argument("--omegas", default="0.3,0.5,1,50,60,100,200", help="omega_n, pi rad/s")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--jsonl", default=None, help="also write one JSON line per episode here")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", message=".*out of date.*")
    rows = []
    out = open(args.jsonl, "w") if args.jsonl else None  # noqa: SIM115 - closed below
    for agent in args.agents.split(","):
        for om in (float(x) for x in args.omegas.split(",")):
            for seed in (int(s) for s in args.seeds.split(",")):
                rows.append(episode(agent, om, seed))
                if out:
                    out.write(json.dumps(rows[-1]) + "\n")
                    out.flush()
    if out:
        out.close()
    print("| agent | episodes | estimate | 95 % interval excludes the truth | bound | bound on the wrong side | "
          "no estimate, no bound |")
    print("|---|---|---|---|---|---|---|")
    for agent in args.agents.split(","):
        r = [x for x in rows if x["agent"] == agent]
        wrong = ", ".join(f"{x['omega_pi']:g} pi s{x['seed']} -> {x['estimate_pi']:.3g} pi" for x in r if x["wrong"])
        print(f"| {agent} | {len(r)} | {sum(x['ok'] for x in r)} | {sum(x['wrong'] for x in r)}"
              f"{f' ({wrong})' if wrong else ''} | {sum(x['bound'] is not None for x in r)} | "
              f"{sum(x['bound_wrong'] for x in r)} | {sum(not x['ok'] and x['bound'] is None for x in r)} |")


if __name__ == "__main__":
    main()
