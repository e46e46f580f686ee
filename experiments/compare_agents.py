"""Adaptive against grid probing on live physics: error against probing cost for every agent.

    python experiments/compare_agents.py [--physics tilelink] [--objects 20] [--seed 0]

The same seeded hidden objects (the env's ``plate_env.objects.ObjectPrior``: omega_n log-uniform 3.5pi-33pi, alpha
30-60 deg) for every agent configuration:
the paper's grid at several densities (its own Lorentzian estimate, and the same probes through the atlas
posterior), coarse_to_fine at several budgets, bayes at several stopping targets, and the shipped PPO policy if
present. Per configuration: median and 90th-percentile relative error of omega_n_hat, probes, simulated and wall
seconds. Then, for each error level a grid configuration reaches, the simulated seconds bayes needs for the same
median error (interpolated along its error-cost curve) as a ratio. Writes experiments/results/compare_agents.md
and .png. Episodes print a progress bar.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import gymnasium as gym
import numpy as np

import plate_env  # noqa: F401 - registers the env
from plate_env.bench.reporting import median_p90
from plate_env.core.objects import ObjectPrior
from plate_env.env.episode import run_episode
from plate_env.plotting import new_figure, save_figure
from plate_env_agents import make_agent


def configurations(quick: bool) -> list[tuple[str, str, dict]]:
    grid_n = (6, 10, 16, 30) if quick else (6, 8, 10, 16, 22, 30)
    out = [(f"grid n={n}", "grid", dict(n=n)) for n in grid_n]
    out += [(f"grid n={n} + atlas", "grid", dict(n=n, method="atlas")) for n in grid_n]
    out += [(f"coarse_to_fine {c}+{f}", "coarse_to_fine", dict(n_coarse=c, n_fine=f))
            for c, f in ((4, 2), (6, 4), (8, 8))]
    targets = (0.15, 0.06, 0.03) if quick else (0.2, 0.1, 0.06, 0.04, 0.03, 0.02)
    out += [(f"bayes target={t:g}", "bayes", dict(target_rel=t)) for t in targets]
    if Path("agents/models/ppo_plate.zip").exists():
        out.append(("ppo", "ppo", {}))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--physics", default="tilelink")
    ap.add_argument("--objects", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-probes", type=int, default=30)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    from tqdm.auto import tqdm

    objs = ObjectPrior().sample(args.objects, args.seed)  # the env's prior: the same objects for every agent
    env = gym.make("PlateRotation-v0", physics=args.physics, max_probes=args.max_probes)
    rows = []
    for label, name, kw in configurations(args.quick):
        agent = make_agent(name, **kw)
        errs, probes, sims, walls, fails = [], [], [], [], 0
        for i, (w, a) in enumerate(tqdm(objs, desc=label, leave=False)):
            r = run_episode(env, agent, seed=args.seed * 1000 + i, options={"omega_n": w, "alpha": a})
            if r.estimate.ok:
                errs.append(r.relative_error)
            else:
                fails += 1
                errs.append(1.0)  # the env's cap: a missing estimate counts as 100 % error
            probes.append(r.n_probes)
            sims.append(r.sim_s)
            walls.append(r.wall_s)
        med, p90 = median_p90(errs)
        rows.append(dict(label=label, agent=name, med=med, p90=p90,
                         probes=float(np.mean(probes)), sim=float(np.median(sims)), wall=float(np.median(walls)),
                         fails=fails))
        print(f"{label:28s} median {100 * rows[-1]['med']:5.1f} %  p90 {100 * rows[-1]['p90']:6.1f} %  "
              f"probes {rows[-1]['probes']:5.1f}  sim {rows[-1]['sim']:5.1f} s  wall {rows[-1]['wall']:5.2f} s  "
              f"no estimate {fails}")
    env.close()
    bayes = sorted((r for r in rows if r["agent"] == "bayes"), key=lambda r: r["sim"])
    lines = [f"# Probing agents on live {args.physics}: error against probing cost", "",
             f"{args.objects} seeded hidden objects (omega_n log-uniform 3.5pi-33pi, alpha 30-60 deg, seed "
             f"{args.seed}), budget {args.max_probes} probes. A missing estimate counts as 100 % error. "
             "Regenerate: `python experiments/compare_agents.py`.", "",
             "| agent | median rel. error | 90th pct | probes (mean) | simulated s (median) | wall s (median) | "
             "no estimate |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['label']} | {100 * r['med']:.1f} % | {100 * r['p90']:.1f} % | {r['probes']:.1f} | "
              f"{r['sim']:.1f} | {r['wall']:.2f} | {r['fails']} |" for r in rows]
    lines += ["", "## Probing seconds bayes needs at each grid configuration's median error", "",
              "| grid configuration | its median error | its simulated s | bayes simulated s for that error | ratio |",
              "|---|---|---|---|---|"]
    for g in (r for r in rows if r["agent"] == "grid"):
        ok = [b for b in bayes if b["med"] <= g["med"]]
        if ok:
            need = min(b["sim"] for b in ok)
            lines.append(f"| {g['label']} | {100 * g['med']:.1f} % | {g['sim']:.1f} | {need:.1f} | "
                         f"{need / g['sim']:.2f} |")
        else:
            lines.append(f"| {g['label']} | {100 * g['med']:.1f} % | {g['sim']:.1f} | not reached | - |")
    out = Path("experiments/results/compare_agents")
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    _plot(rows, str(out.with_suffix(".png")), args.physics)
    print("\n".join(lines))


def _plot(rows, path: str, physics: str) -> None:
    fig, ax = new_figure(figsize=(7, 4.5))
    groups: dict[str, list] = {}
    for r in rows:
        key = r["agent"] + (" + atlas" if r["label"].endswith("+ atlas") else "")
        groups.setdefault(key, []).append(r)
    for key, rs in groups.items():
        rs = sorted(rs, key=lambda r: r["sim"])
        ax.plot([r["sim"] for r in rs], [100 * r["med"] for r in rs], "o-", label=key)
    ax.set_xlabel("simulated probing seconds (median per identification)")
    ax.set_ylabel("median relative error of omega_n_hat [%]")
    ax.set_yscale("log")
    ax.set_title(f"Error against probing cost, live {physics}")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    save_figure(fig, path, dpi=100)


if __name__ == "__main__":
    main()
