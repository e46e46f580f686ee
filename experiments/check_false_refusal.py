"""False-refusal rate of the episode-end predictive check on in-model episodes (issue 38 item 3).

An in-model episode is one whose probes the env's forward model describes: on ``PlateRotationAtlas-v0`` / ``-v1``
every probe is drawn from the very atlas the env's estimate reads (the check should refuse about ``CHECK_P_MIN`` of
them, or fewer: it checks at the best fit); on the live ``PlateRotation-v0`` the probes come from the tile-link
point mass the atlas was built from (its interpolation error between nodes is the model's, not the data's fault).

Per episode (``run_episode`` of each shipped agent, seeds ``--seed0 ...``) it records the check of the env's own
estimate (the one its reward charges) under the current rule and under the rule before issue 38
(``CHECK_NODE_SHARE = 0``: probes not allowed to move between the atlas's omega_n nodes), and the check of the
bench's estimate (the agent's estimate model). Episodes go to ``experiments/results/check_false_refusal/<env>.jsonl``
(appended; a seed already there is skipped, so a run can be resumed or extended); ``--report`` writes
``experiments/results/check_false_refusal.{md,json}`` with Wilson and Clopper-Pearson 95 % intervals.

Commands::

    python experiments/check_false_refusal.py --env PlateRotationAtlas-v0 --episodes 1000
    python experiments/check_false_refusal.py --env PlateRotationAtlas-v1 --episodes 1000
    python experiments/check_false_refusal.py --env PlateRotation-v0 --episodes 200
    python experiments/check_false_refusal.py --report
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import time
import warnings
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
RUNS = RESULTS / "check_false_refusal"


@contextlib.contextmanager
def node_share(value: float):
    """The check's node share set to ``value`` for the block (the rule before issue 38: 0)."""
    from plate_env.identify import inference

    old = inference.CHECK_NODE_SHARE
    inference.CHECK_NODE_SHARE = value
    try:
        yield
    finally:
        inference.CHECK_NODE_SHARE = old


def episode_record(env, agent, seed: int) -> dict:
    """One episode: the env's estimate check (now and before), the bench's estimate and its check."""
    from plate_env.env.episode import run_episode
    from plate_env.identify.forward import load_forward_model
    from plate_env.identify.inference import identify_atlas, predictive_check

    r = run_episode(env, agent, seed=seed)
    e = env.unwrapped
    env_est = e.estimate()  # the estimate the env's reward charged (its own posterior of these probes)
    rec = {"seed": seed, "agent": agent.name, "n_probes": r.n_probes, "omega_n_true_rad_s": r.omega_n_true,
           "alpha_true_rad": r.alpha_true, "probes": r.probes.to_rows(),
           "env_ok": env_est.ok, "env_reason": None if env_est.ok else env_est.reason,
           "env_error": env_est.relative_error(r.omega_n_true) if env_est.ok else None,
           "bench_ok": r.estimate.ok, "bench_error": r.relative_error if r.estimate.ok else None,
           "bench_p": None if r.estimate.check is None else r.estimate.check.p_value,
           "env_p": None if env_est.check is None else env_est.check.p_value, "env_p_before": None}
    # the shipped forward model of the env's physics on the same probes (the env's reward before run_episode handed
    # it the agent's estimate model), under the current rule and the rule before
    shipped = load_forward_model(f"{e.source}/{e.model}", e.known_inputs())
    ship = identify_atlas(e.table(), shipped)
    rec["shipped_p"] = None if ship.check is None else ship.check.p_value
    rec["shipped_p_before"] = None
    if ship.check is not None and ship.posterior is not None:
        with node_share(0.0):
            rec["shipped_p_before"] = predictive_check(shipped, e.table(), ship.posterior).p_value
    if env_est.check is not None and env_est.posterior is not None:
        with node_share(0.0):
            rec["env_p_before"] = predictive_check(e.posterior_state().fm, e.table(), env_est.posterior).p_value
    return rec


def run(env_id: str, agents: list[str], episodes: int, seed0: int) -> Path:
    import gymnasium as gym

    import plate_env  # noqa: F401  (registers the ids)
    from plate_env_agents import make_agent

    RUNS.mkdir(parents=True, exist_ok=True)
    out = RUNS / f"{env_id}.jsonl"
    done = set()
    if out.exists():
        done = {(d["agent"], d["seed"]) for d in map(json.loads, out.read_text().splitlines())}
    env = gym.make(env_id)
    made = {name: make_agent(name) for name in agents}
    with out.open("a") as fh:
        for seed in range(seed0, seed0 + episodes):  # agents interleaved: a cut run stays balanced
            for name in agents:
                if (name, seed) in done:
                    continue
                t0 = time.perf_counter()
                try:
                    rec = episode_record(env, made[name], seed)
                except Exception as exc:  # noqa: BLE001 - recorded, not hidden: the report counts them
                    rec = {"seed": seed, "agent": name, "error": f"{type(exc).__name__}: {exc}"}
                rec["env"], rec["wall_s"] = env_id, time.perf_counter() - t0
                fh.write(json.dumps(rec) + "\n")
                fh.flush()
    return out


def stored(paths: list[Path]) -> Path:
    """The check recomputed on stored live bayes episodes (their probe tables; ``experiments/forward_models.py``'s
    cache of live point-mass episodes, default known inputs): the estimate of record is bayes's estimate model's,
    the shipped model's under the rule now and before. Written as ``PlateRotation-v0-stored.jsonl``."""
    from plate_env.core.probe_table import ProbeTable
    from plate_env.identify.forward import load_forward_model
    from plate_env.identify.inference import identify_atlas, predictive_check
    from plate_env_agents.bayes import BayesAgent

    agent = BayesAgent()
    agent.fm = shipped = load_forward_model("tilelink/pointmass")
    design = agent.estimate_model()
    RUNS.mkdir(parents=True, exist_ok=True)
    out = RUNS / "PlateRotation-v0-stored.jsonl"
    with out.open("w") as fh:
        for path in paths:
            for line in path.read_text().splitlines():
                d = json.loads(line)
                rows = d["table"]
                table = ProbeTable.from_arrays(*([r[k] for r in rows] for k in (
                    "f_p_hz", "a_p_deg", "omega_b_deg_s", "stderr_deg_s", "unstable")))
                rec = {"seed": f"{path.stem}:{d['i']}", "agent": "bayes", "n_probes": len(table), "source": path.name}
                for name, fm in (("env", design), ("shipped", shipped)):
                    est = identify_atlas(table, fm)
                    rec[f"{name}_p"] = None if est.check is None else est.check.p_value
                    rec[f"{name}_p_before"] = None
                    if est.check is not None and est.posterior is not None:
                        with node_share(0.0):
                            rec[f"{name}_p_before"] = predictive_check(fm, table, est.posterior).p_value
                    rec[f"{name}_ok"] = est.ok
                    rec[f"{name}_error"] = est.relative_error(d["omega_n"]) if est.ok else None
                rec.update(bench_p=rec["env_p"], bench_ok=rec["env_ok"], bench_error=rec["env_error"])
                fh.write(json.dumps(rec) + "\n")
    return out


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (0.0 if k == 0 else max(0.0, c - h), 1.0 if k == n else min(1.0, c + h))


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    from scipy.stats import beta

    a = 1 - level
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return (lo, hi)


def refused(p: float | None, p_min: float) -> bool:
    return p is not None and p < p_min


def _now(d: dict) -> float | None:
    """The p-value of the check of the estimate the env's reward charges now. Records written before run_episode
    handed the agent's estimate model to the env (no ``shipped_p``) hold the shipped model's in ``env_p``; for an
    agent with its own estimate model (bayes) the env's estimate is now the bench's."""
    if "shipped_p" in d or d["agent"] != "bayes":
        return d["env_p"]
    return d["bench_p"]


def _columns(d: dict) -> dict[str, float | None]:
    return {"now": _now(d), "shipped": d.get("shipped_p", d["env_p"] if "shipped_p" not in d else None),
            "shipped_before": d.get("shipped_p_before", d["env_p_before"])}


COLUMNS = {"now": "env reward's estimate (= bench score's), rule now",
           "shipped": "shipped forward model, rule now",
           "shipped_before": "shipped forward model, rule before (the issue's)"}


def report() -> None:
    from plate_env.identify.estimate import CHECK_P_MIN
    from plate_env.identify.inference import CHECK_DRAWS, CHECK_NODE_SHARE

    rows = []
    for path in sorted(RUNS.glob("*.jsonl")):
        recs = {}
        for line in path.read_text().splitlines():
            d = json.loads(line)
            recs.setdefault((d["agent"], d["seed"]), d)  # one record per (agent, seed)
        recs = list(recs.values())
        for agent in sorted({d["agent"] for d in recs}):
            mine = [d for d in recs if d["agent"] == agent and "error" not in d]
            errors = sum(1 for d in recs if d["agent"] == agent and "error" in d)
            n = len(mine)
            row = {"env": path.stem, "agent": agent, "episodes": n, "errors": errors,
                   "seeds": [min((d["seed"] for d in mine), default=None), max((d["seed"] for d in mine),
                                                                               default=None)]}
            cols = [_columns(d) for d in mine]
            for col in COLUMNS:
                k = sum(refused(c[col], CHECK_P_MIN) for c in cols)
                row[col] = {"refused": k, "rate": k / n if n else None, "wilson95": wilson(k, n),
                            "clopper_pearson95": clopper_pearson(k, n),
                            "refused_seeds": [d["seed"] for d, c in zip(mine, cols, strict=True)
                                              if refused(c[col], CHECK_P_MIN)]}
            row["smallest_p_now"] = min((c["now"] for c in cols if c["now"] is not None), default=None)
            shared = [d for d in mine if "shipped_p" in d and agent != "grid"]
            row["env_equals_bench"] = [sum(1 for d in shared if d["env_ok"] == d["bench_ok"] and (
                not d["env_ok"] or d["env_error"] == d["bench_error"])), len(shared)]
            rows.append(row)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "check_false_refusal.json").write_text(json.dumps(
        {"command": "python experiments/check_false_refusal.py --env ENV --episodes N; ... --report",
         "p_min": CHECK_P_MIN, "check_draws": CHECK_DRAWS, "check_node_share": CHECK_NODE_SHARE, "columns": COLUMNS,
         "rows": rows}, indent=1) + "\n")

    def cell(c: dict) -> str:
        lo, hi = c["clopper_pearson95"]
        wl, wh = c["wilson95"]
        return f"{c['refused']} ({c['rate']:.3g}; CP {lo:.2g}-{hi:.2g}; W {wl:.2g}-{wh:.2g})"

    lines = ["# False refusals of the episode-end predictive check on in-model episodes", "",
             "Command: `python experiments/check_false_refusal.py --env ENV --episodes N` per env (and agents), then "
             "`--report`; episodes in `experiments/results/check_false_refusal/ENV.jsonl`, seeds from 1000.", "",
             f"An episode is refused when the check's p-value is below {CHECK_P_MIN:g} (replicates: {CHECK_DRAWS}, "
             f"p = (k + 1) / ({CHECK_DRAWS} + 1), smallest {1 / (CHECK_DRAWS + 1):.2g}). Rule now: each probe may "
             f"move along omega_n by max(the member's blur, {CHECK_NODE_SHARE:g} x the atlas's median omega_n node "
             "interval); rule before: the member's blur only (0 for the shipped point mass). Columns: "
             + "; ".join(f"**{k}**: {v}" for k, v in COLUMNS.items())
             + ". Cells: refused (rate; Clopper-Pearson (CP) and Wilson (W) 95 % intervals). grid estimates by the "
             "Lorentz method: its bench score has no check, the env's reward reads the atlas.", "",
             "| env | agent | episodes | " + " | ".join(COLUMNS) + " | smallest p now | env = bench | errors |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if not r["episodes"]:
            continue
        sp = "-" if r["smallest_p_now"] is None else f"{r['smallest_p_now']:.2g}"
        eq = "-" if not r["env_equals_bench"][1] else "{} of {}".format(*r["env_equals_bench"])
        lines.append(f"| {r['env']} | {r['agent']} | {r['episodes']} | "
                     + " | ".join(cell(r[c]) for c in COLUMNS) + f" | {sp} | {eq} | {r['errors']} |")
    (RESULTS / "check_false_refusal.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="PlateRotationAtlas-v0")
    ap.add_argument("--agents", default=None, help="comma-separated (default: every shipped agent)")
    ap.add_argument("--episodes", type=int, default=1000)
    ap.add_argument("--seed0", type=int, default=1000)
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--stored", nargs="+", type=Path, default=None,
                    help="recompute the check on stored live bayes episodes (experiments/cache/forward_models_bayes_"
                         "s510.jsonl s520.jsonl)")
    args = ap.parse_args(argv)
    if args.report:
        report()
        return 0
    if args.stored:
        print(stored(args.stored))
        return 0
    from plate_env_agents import AGENT_NAMES

    warnings.filterwarnings("ignore", category=DeprecationWarning)
    agents = args.agents.split(",") if args.agents else list(AGENT_NAMES)
    print(run(args.env, agents, args.episodes, args.seed0))
    return 0


if __name__ == "__main__":
    sys.exit(main())
