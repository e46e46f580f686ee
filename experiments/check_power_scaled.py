"""How often the predictive check refuses stored live bayes episodes whose rates are scaled by a wrong factor (data
no object of the atlas makes at that scale, e.g. a mis-set gyro gain), under the rule now and under the rule of
99358cc (omega_n node share only): what the alpha interpolation error in the check's scale costs in power (issue 38
item 3). Reads ``experiments/cache/forward_models_bayes_s510.jsonl`` (the first ``--episodes``); prints a markdown
table. ``python experiments/check_power_scaled.py --episodes 100 --scales 0.8 1.25``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--scales", type=float, nargs="+", default=[0.8, 1.25])
    ap.add_argument("--cache", type=Path, default=HERE / "cache" / "forward_models_bayes_s510.jsonl")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from check_false_refusal import checks

    from plate_env.core.probe_table import ProbeTable
    from plate_env.identify.estimate import CHECK_P_MIN
    from plate_env.identify.forward import load_forward_model
    from plate_env_agents.bayes import BayesAgent

    agent = BayesAgent()
    agent.fm = load_forward_model("tilelink/pointmass")
    fm = agent.estimate_model()
    lines = args.cache.read_text().splitlines()[: args.episodes]
    print("| scale | episodes | refused now | refused node share only | median p now | median p node |")
    print("|---|---|---|---|---|---|")
    for scale in [1.0, *args.scales]:
        now, node = [], []
        for line in lines:
            rows = json.loads(line)["table"]
            t = ProbeTable.from_arrays(*([r[k] * (scale if k == "omega_b_deg_s" else 1) for r in rows] for k in (
                "f_p_hz", "a_p_deg", "omega_b_deg_s", "stderr_deg_s", "unstable")))
            c = checks(fm, t, "x")
            now.append(c["x_p"] if c["x_p"] is not None else 1.0)
            node.append(c["x_p_node"] if c["x_p_node"] is not None else 1.0)
        med = lambda v: sorted(v)[len(v) // 2]  # noqa: E731
        print(f"| {scale:g} | {len(lines)} | {sum(p < CHECK_P_MIN for p in now)} | "
              f"{sum(p < CHECK_P_MIN for p in node)} | {med(now):.2g} | {med(node):.2g} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
