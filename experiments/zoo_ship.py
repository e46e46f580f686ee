"""Ship a zip trained by experiments/zoo_algos.py for the leaderboards (issue 38: SAC and TD3 at SB3's defaults,
20,000 steps, beside the shipped PPO), with a JSON sidecar saying how it was made:

    python experiments/zoo_ship.py --run zoo_algos_sac20k:sac --name sac_atlas [--dest experiments/results/models]

reads the run ``sac`` of experiments/results/zoo_algos_sac20k.json (written by ``zoo_algos.py --keep DIR``),
copies its zip to ``DEST/NAME.zip`` and writes ``DEST/NAME.json``: the env_kwargs it trained with (the ``sb3:``
agent reads its observation and action layout there: band, amplitudes, windows), the rl-zoo3 command, the conf
entry it trained from (plate_env_agents/hyperparams/ALGO.yml), the steps the zip holds, the seed, the wall time
and load, the versions, the commit, the zip's SHA-256 and size, and the 100-episode score of zoo_algos.py. The zip
is the file rl-zoo3 saved, unchanged (SB3's ``ALGO.load`` and the bench's ``sb3:ALGO:PATH`` both read it); the
shipped zips are then slimmed to data and actor by experiments/zoo_slim.py, which updates the sidecar.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import platform
import shutil
from datetime import datetime, timezone
from pathlib import Path

RESULTS = Path(__file__).parent / "results"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--run", required=True, help="STEM:ALGO, a run of experiments/results/STEM.json")
    ap.add_argument("--name", required=True, help="the shipped file's stem, e.g. sac_atlas")
    ap.add_argument("--dest", type=Path, default=Path("experiments/results/models"))
    args = ap.parse_args()
    stem, _, algo = args.run.partition(":")
    doc = json.loads((RESULTS / f"{stem}.json").read_text())
    runs = [r for r in doc["runs"] if r["algo"] == algo]
    if len(runs) != 1:
        raise SystemExit(f"--run {args.run}: {len(runs)} runs of {algo!r} in {stem}.json, need exactly one")
    run = runs[0]
    import gymnasium
    import stable_baselines3
    import torch

    from plate_env_agents.zoo import hyperparams_of

    env_id = doc.get("env_id", "PlateRotationAtlas-v0")
    dest = args.dest / f"{args.name}.zip"
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(run["zip"], dest)
    blob = dest.read_bytes()
    entry = hyperparams_of(algo)[env_id]
    side = {"algo": algo, "env_id": env_id, "env_kwargs": entry.get("env_kwargs", {}), "command": run["command"],
            "seed": 0,
            "steps": run["steps_trained"], "conf_file": f"plate_env_agents/hyperparams/{algo}.yml",
            "hyperparams": entry,
            "train_wall_s": run.get("wall_s"), "load_before_after": [run.get("load_before"), run.get("load_after")],
            "torch_threads": 1, "commit": doc["commit"], "made_by": f"experiments/zoo_algos.py ({stem}.json)",
            "score": {k: run[k] for k in ("episodes", "median_rel_error", "p90_rel_error", "with_estimate",
                                          "mean_probes")} | {"env_seeds": "100000 + i", "deterministic": True},
            "versions": {"python": platform.python_version(), "rl_zoo3": doc["rl_zoo3"],
                         "stable_baselines3": stable_baselines3.__version__, "torch": torch.__version__,
                         "gymnasium": gymnasium.__version__},
            "sha256": hashlib.sha256(blob).hexdigest(), "model_bytes": len(blob),
            "date": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    dest.with_suffix(".json").write_text(json.dumps(side, indent=2) + "\n")
    print(f"{dest} ({len(blob) / 1e6:.1f} MB) and {dest.with_suffix('.json')}")


if __name__ == "__main__":
    main()
