"""Slim a shipped SB3 zip to what its deterministic action needs (issue 38: the SAC and TD3 leaderboard zips,
5.4 and 10 MB as rl-zoo3 saved them, carried optimiser states and critics no ``sb3:`` agent reads):

    python experiments/zoo_slim.py FULL.zip --out experiments/results/models/sac_atlas.zip

writes OUT with :func:`plate_env_agents.sb3_zip.slim_zip` (``data`` unchanged; ``policy.pth`` with the actor's
tensors only for SAC/TD3/DDPG, the whole policy for PPO/A2C; optimiser states dropped) and updates OUT's JSON
sidecar (``OUT.json``, written by experiments/zoo_ship.py for the full zip): ``sha256``/``model_bytes`` become the
slim zip's, and ``slimmed`` records the full zip's SHA-256 and size, this command and the members dropped. The full
zip's ``sha256`` in the sidecar must match FULL (so the sidecar describes the run that made it); ``--force`` skips
that check. The bench's ``sb3:`` agent acts the same with either zip (tests/test_sb3_zips.py); SB3's ``ALGO.load``
needs the full one.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("full", type=Path, help="the zip rl-zoo3 saved (zoo_ship.py's copy)")
    ap.add_argument("--out", type=Path, required=True, help="the slim zip; its sidecar OUT.json is updated")
    ap.add_argument("--force", action="store_true", help="do not check FULL's SHA-256 against the sidecar's")
    args = ap.parse_args()
    from plate_env_agents.sb3_zip import slim_zip

    side_path = args.out.with_suffix(".json")
    side = json.loads(side_path.read_text()) if side_path.exists() else {}
    full_sha = hashlib.sha256(args.full.read_bytes()).hexdigest()
    recorded = side.get("slimmed", {}).get("from_sha256", side.get("sha256"))
    if side and recorded != full_sha and not args.force:
        raise SystemExit(f"{args.full}: sha256 {full_sha[:12]}, its sidecar {side_path} records "
                         f"{str(recorded)[:12]}: not the zip the sidecar describes (--force to slim anyway)")
    info = slim_zip(args.full, args.out, side.get("algo"))
    blob = args.out.read_bytes()
    if side:
        side["sha256"] = hashlib.sha256(blob).hexdigest()
        side["model_bytes"] = len(blob)
        side["slimmed"] = {"from_sha256": full_sha, "from_bytes": args.full.stat().st_size,
                           "command": f"python experiments/zoo_slim.py {args.full.name} --out {args.out.as_posix()}",
                           "dropped": info["dropped"], "tensors": info["tensors"],
                           "note": "sb3: agents act the same with either zip; SB3's ALGO.load needs the full one"}
        side_path.write_text(json.dumps(side, indent=2) + "\n")
    print(f"{args.out}: {len(blob):,} bytes (from {args.full.stat().st_size:,}); kept {info['kept']}, dropped "
          f"{info['dropped']}")


if __name__ == "__main__":
    main()
