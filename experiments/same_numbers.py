"""Compare two leaderboard JSONs (``plate-env bench --json``, or the JSON experiments/leaderboard.py wrote before it
was folded into the CLI) field by field, wall times aside.

    python experiments/same_numbers.py experiments/results/leaderboard_tilelink-v0.json \
        experiments/results/leaderboard_tilelink-v0_process2.json

Exit 0 and "identical" when every number but the wall seconds per decision is equal (bit for bit), else the first
differences and exit 1. Used to check that two fresh processes give the same leaderboard.
"""

from __future__ import annotations

import json
import sys

#: Fields that are wall-clock measurements (differ between runs by nature).
WALL = ("seconds_per_decision",)


def diffs(a, b, path: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = [] if set(a) == set(b) else [f"{path}: keys {sorted(set(a) ^ set(b))}"]
        return out + [d for k in sorted(set(a) & set(b)) if k not in WALL for d in diffs(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} against {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in diffs(x, y, f"{path}[{i}]")]
    return [] if a == b or (a != a and b != b) else [f"{path}: {a!r} != {b!r}"]


def main() -> None:
    a, b = (json.loads(open(p).read()) for p in sys.argv[1:3])
    found = diffs(a, b)
    n = sum(len(x["budgets"]) for x in a["agents"])
    print("identical" if not found else "\n".join(found[:20]), f"({len(a['agents'])} agents, {n} agent-budgets, "
          f"wall seconds per decision left out)")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
