"""Calibrate the predictive check (issue 28, item 3): how many honest sweeps it rejects, and that data no object
could make is rejected.

    python experiments/predictive_check.py --objects 120 --episodes 60 [--executor pool]   # the results file

Honest sweeps: the within-model test set of experiments/forward_models.py (``TEST``: tilelink point-mass objects
from the identification prior, seed 200, 10-40 Hz at 1 Hz, 3 and 12 deg; the resumable caches in
experiments/cache, simulated if missing), the first ``--objects`` of it, identified by the shipped
``tilelink/pointmass`` forward model. For each sweep (3 deg, 12 deg, both): the check's p-value, whether the check
rejects it (p < ``CHECK_P_MIN``), whether the alpha edge rule flags it, and the 68 % / 95 % coverage of the
estimates that remain against those of every sweep (so the cost to coverage is measured, not assumed). Bad data:
each honest sweep's omega_B set to 0, made negative, or multiplied by 100 (the share given no estimate, and in
brackets the share the check itself rejects; the rest are flagged by the alpha edge rule). Writes
experiments/results/predictive_check.md and .json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shlex
import sys
from pathlib import Path

import numpy as np
from common import CACHE, POINTMASS, TEST, episodes, sets_by_amplitude

from plate_env.build.eval_sets import run_eval_set  # noqa: E402
from plate_env.core.probe_table import ProbeTable  # noqa: E402
from plate_env.identify.estimate import CHECK_P_MIN  # noqa: E402
from plate_env.identify.forward import load_forward_model  # noqa: E402
from plate_env.identify.inference import identify_atlas  # noqa: E402
from plate_env.run.executor import add_executor_argument  # noqa: E402

RESULTS = Path("experiments/results")


def covered(est, truth: float, level: str) -> bool:
    lo, hi = est.omega_n_ci68 if level == "68" else est.omega_n_ci95
    return lo <= truth <= hi


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=TEST.n)
    ap.add_argument("--episodes", type=int, default=0, help="also this many live bayes episodes (seed 520, "
                    "experiments/forward_models.py's test episodes, resumable cache)")
    add_executor_argument(ap)
    args = ap.parse_args()
    es = dataclasses.replace(TEST, n=args.objects)
    sets = sets_by_amplitude(run_eval_set(es, lambda _: POINTMASS, args.executor, cache_dir=CACHE), es)
    truth = [o.omega_n for o in es.objects()]
    fm = load_forward_model("tilelink/pointmass")
    command = shlex.join(["python", "experiments/predictive_check.py", *sys.argv[1:]])
    lines = ["# The predictive check on honest and impossible sweeps", "", f"Command: `{command}`.", "",
             f"Forward model `tilelink/pointmass`; honest sweeps: the first {es.n} objects of the within-model test "
             f"set (seed {es.seed}, 10-40 Hz at 1 Hz). A sweep is rejected when its predictive p-value is below "
             f"{CHECK_P_MIN:g} (`plate_env.inference.predictive_check`; the smallest p-value 4000 replicates can "
             "give is 2.5e-4). Coverage against the truth, before (every sweep's posterior, check ignored) and "
             "after (the sweeps given an estimate: not rejected by the check, not flagged by the alpha edge rule, "
             "not answered with a bound at an omega_n edge; their number in the column 'estimates').", "",
             "| sweeps | n | rejected by the check | flagged by the alpha edge | estimates | smallest p | 68 % "
             "coverage before / after | 95 % coverage before / after | no estimate (by the check): zero | negative | "
             "x100 |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    numbers: dict = {"command": command, "p_min": CHECK_P_MIN, "objects": es.n, "seed": es.seed, "sets": {}}
    for amps, tables in sets.items():
        ests = [identify_atlas(t, fm) for t in tables]
        p = np.array([e.check.p_value for e in ests])
        rejected = p < CHECK_P_MIN
        edge = np.array([e.posterior.alpha_edge() is not None for e in ests])
        kept = [i for i, e in enumerate(ests) if e.ok]
        cov = {lvl: (float(np.mean([covered(e, w, lvl) for e, w in zip(ests, truth, strict=True)])),
                     float(np.mean([covered(ests[i], truth[i], lvl) for i in kept])) if kept else math.nan)
               for lvl in ("68", "95")}
        bad = {}
        for name, f in (("zero", lambda y: 0.0 * y), ("negative", lambda y: -np.abs(y)), ("x100", lambda y: 100 * y)):
            bad_ests = [identify_atlas(ProbeTable(t.f_p_hz, t.a_p_deg, f(t.omega_b_deg_s), t.stderr_deg_s,
                                                  t.unstable), fm) for t in tables]
            bad[name] = (float(np.mean([not e.ok for e in bad_ests])),
                         float(np.mean([not e.check.passed for e in bad_ests])))
        numbers["sets"][amps] = {"n": len(tables), "rejected": float(rejected.mean()),
                                 "n_rejected": int(rejected.sum()), "alpha_edge": float(edge.mean()),
                                 "n_estimates": len(kept),
                                 "p_values": p.tolist(), "coverage68": cov["68"], "coverage95": cov["95"],
                                 "bad_rejected": bad}
        lines.append(f"| A_p = {amps} deg | {len(tables)} | {rejected.mean():.3f} ({int(rejected.sum())}) | "
                     f"{edge.mean():.3f} ({int(edge.sum())}) | {len(kept)} | {p.min():.2g} | "
                     f"{cov['68'][0]:.2f} / {cov['68'][1]:.2f} | {cov['95'][0]:.2f} / {cov['95'][1]:.2f} | "
                     + " | ".join(f"{bad[k][0]:.2f} ({bad[k][1]:.2f})" for k in ("zero", "negative", "x100")) + " |")
    if args.episodes:
        from plate_env_agents.bayes import BayesAgent

        eps = episodes(args, fm, 520)
        agent = BayesAgent()
        agent.fm = fm
        # each episode's probes identified again with the agent's estimate model (the cache may hold estimates of
        # an older check)
        ests = [identify_atlas(ProbeTable.from_rows(e["table"]), agent.estimate_model()) for e in eps]
        p = np.array([e.check.p_value for e in ests])
        rej = int(np.sum(p < CHECK_P_MIN))
        numbers["bayes_episodes"] = {"n": len(eps), "n_rejected": rej, "p_values": p.tolist(),
                                     "no_estimate": int(sum(not e.ok for e in ests))}
        lines += ["", f"Live bayes episodes (tilelink, prior objects, seed 520, the agent's own estimate model): "
                  f"{rej} of {len(eps)} rejected by the check (smallest p {p.min():.2g}); "
                  f"{numbers['bayes_episodes']['no_estimate']} without an estimate for any reason."]
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "predictive_check.md").write_text("\n".join(lines) + "\n")
    (RESULTS / "predictive_check.json").write_text(json.dumps(numbers, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
