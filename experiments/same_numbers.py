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

from common import diffs


def main() -> None:
    a, b = (json.loads(open(p).read()) for p in sys.argv[1:3])
    found = diffs(a, b)
    n = sum(len(x["budgets"]) for x in a["agents"])
    print("identical" if not found else "\n".join(found[:20]), f"({len(a['agents'])} agents, {n} agent-budgets, "
          f"wall seconds per decision left out)")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
