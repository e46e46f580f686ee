"""``plate-env build``: the builders of :mod:`plate_env.build` (its parser:
:func:`plate_env.build.commands.add_build_parser`); ``policy`` trains with the agents' package, which only the
command line imports."""

from __future__ import annotations

import argparse
from pathlib import Path

from plate_env.build.commands import add_build_parser, run_build

add_parser = add_build_parser


def run(args: argparse.Namespace) -> int:
    """``plate-env build``: the builders of plate_env.build; ``policy`` trains with the agents' package, which only
    the command line imports (the seam to the agents)."""
    if args.artifact != "policy":
        return run_build(args, args.argv[1:])
    from plate_env.build.provenance import build_record, record_in_manifest
    from plate_env.core.files import check_output
    from plate_env_agents.train import train_policy

    for path in (Path(args.out), Path(args.out).with_suffix(".npz"), Path(args.out).with_suffix(".json")):
        check_output(path, "--out")  # before the training (an hour at the default steps), not at its save
    record = build_record(args.argv[1:])
    meta = train_policy(args.out, record, hyperparams=args.hyperparams, env_id=args.env_id,
                        seed=args.seed, timesteps=args.timesteps, eval_freq=args.eval_freq,
                        eval_episodes=args.eval_episodes, eval_seed=args.eval_seed, threads=args.threads)
    for path in (Path(args.out), Path(args.out).with_suffix(".npz"), Path(args.out).with_suffix(".json")):
        record_in_manifest(path, record)  # a shipped policy's files get their manifest entries
    out, ev = Path(args.out), meta["eval"]
    kept = (f"best eval reward {ev['best_reward']:.4f} at {ev['best_at_timesteps']} steps" if ev["curve"] else
            "no evaluation ran: the last model")
    print(f"trained {meta['timesteps']} steps in {meta['train_wall_s']:.0f} s (seed {meta['seed']}); {kept} -> {out}, "
          f"{out.with_suffix('.npz')}, {out.with_suffix('.json')}")
    return 0
