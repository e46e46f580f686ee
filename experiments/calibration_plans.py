"""Issue 36: what a lab's reference discs buy. K = 1, 2, 3, 5, 8 reference plans of the calibrated reading, each
physics family left out in turn, beside each source's information limit; and the lab-adaptive candidate.

    python experiments/calibration_plans.py study [--draws 8] [--seed 0]
    python experiments/calibration_plans.py plot     # docs/img/calibration_gain.png from the JSON

Sources (each in turn is the lab; the sweeps of ``calibration_study.py``, read from ``experiments/cache``, the
``pmlab`` labs simulated there when missing, about 10 s a lab): ``pointmass`` (120 discs, each its own joint and
contact values: one lab whose discs differ in ways no reference can teach), ``rigid`` (the paper-faithful rigid
tiles, rigid_limit, 20 discs), ``pybullet`` (the PyBullet sheet, 24 discs), ``pmlab`` (8 simulated point-mass labs
of 20 discs, each lab one draw of the joint and contact values). For a lab, the members of its own physics family
are left out of the forward model and every prior is learned from the labs of the *other* families only.

Methods (``--methods``):

- ``offset``: the shipped map (``plate_env.identify.lab_calibration``: member weights + offset, b = 1, scatter
  prior log-normal at the other families' labs' scatter, sd(log) 0.75) = ``calibration_study.py``'s ``offset``;
- ``readings``: the same map with a wide scatter prior (sd(log) ``--log-sd``, 1.5): the references' own residuals
  decide the lab's scatter, the prior over labs only where they are few;
- ``features``: the feature line (log omega_n linear in f0 and log omega_Brmax of the Eq. 9 Lorentzian), its
  coefficients and scatter shrunk toward a hierarchical prior over the other families' labs (scatter sd(log)
  ``--log-sd``); no estimate where the Lorentzian fit fails;
- ``adaptive``: ``features`` and ``readings`` averaged, each disc's predictive a mixture weighted by the
  references' leave-one-out predictive scores (pseudo-BMA; equal weights at K = 1), ``readings`` alone for a disc
  without hump features.

Every predictive integrates the scatter over its posterior on a grid: a scale mixture of normals, heavy-tailed
(Student-t-like) when the references are few. Writes ``experiments/results/calibration_plans.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import common
import numpy as np
from common import SOURCE_FAMILY, Lab

RESULTS = Path("experiments/results")
IMG = Path("docs/img/calibration_gain.png")
KS = (1, 2, 3, 5, 8)
SOURCES = ("pointmass", "rigid", "pybullet", "pmlab")
METHODS = ("offset", "readings", "features", "adaptive")
#: The targets of issue 36 (K = 3 pooled median 95 % width and median error; 95 % coverage band at K = 1, 3, 5;
#: the width of sources whose references line up, in-sample sd <= LINED_UP_SD).
TARGET_WIDTH, TARGET_ERROR, COVERAGE_BAND, LINED_UP_SD, LINED_UP_WIDTH = 1.20, 0.12, (0.90, 0.98), 0.1, 0.60


def load_sources(executor: str) -> tuple[dict[str, list[Lab]], list[str]]:
    """Every source's labs with every member's readings and the hump features."""
    fm, fams = common.all_members()
    data = {}
    for src in SOURCES:
        if src == "pmlab":
            sets = [(f"pmlab{es.seed}", common.data_of("pointmass", executor, es)) for es in common.lab_sets()]
        else:
            sets = [(src, common.source_data(src, None, executor))]
        data[src] = [Lab(name, np.asarray(truth), common.readings_of(name, tables, fm), common.features_of(tables))
                     for name, (truth, tables) in sets]
    return data, fams


# --------------------------------------------------------------------------------------------------- candidates
def as_features(F: np.ndarray, i: int):
    """Row ``i`` of :func:`common.features_of` as ``adaptive_calibration.Features``."""
    return (float(F[i, 1]), float(F[i, 3])) if F[i, 0] == 1 else None


def package_prior(p: common.FeatPrior):
    from plate_env.identify.adaptive_calibration import FeaturePrior

    return FeaturePrior(tuple(float(x) for x in p.m0), tuple(tuple(float(x) for x in r) for r in p.c0),
                        float(p.sigma_median), float(p.log_sd))


def run_draw(lab: Lab, ref: np.ndarray, others: list[int], rd: list, names, priors: dict, methods) -> dict:
    """Each method's predictions of the discs ``others`` from the references ``ref`` (the candidates through the
    package's functions, :mod:`plate_env.identify.adaptive_calibration`); and the adaptive weight."""
    from plate_env.identify import adaptive_calibration as ac
    from plate_env.identify.lab_calibration import fit_lab, predict

    y = np.log(lab.truth[ref])
    feats = [as_features(lab.features, i) for i in range(len(lab.truth))]
    out: dict = {}
    if "offset" in methods:
        post = fit_lab([rd[i] for i in ref], y, names, priors["offset"])
        out["offset"] = [predict(post, rd[i]) for i in others]
    if not {"readings", "features", "adaptive"} & set(methods):
        return out
    weight = None if "adaptive" in methods else 0.5
    lab_post = ac.fit_adaptive([rd[i] for i in ref], [feats[i] for i in ref], y, names, priors["readings"],
                               priors["features"], weight=weight)
    rc = {i: ac.readings_cdf(lab_post.readings, rd[i]) for i in others}
    fc = {i: ac.feature_cdf(lab_post.line, feats[i]) for i in others}
    if "readings" in methods:
        out["readings"] = [ac.mixed_prediction(None, rc[i], 0.0) for i in others]
    if "features" in methods:
        out["features"] = [ac.mixed_prediction(fc[i], None, 1.0) if fc[i] is not None
                           else ac.mixed_prediction(None, None, 1.0) for i in others]
    if "adaptive" in methods:
        out["adaptive"] = [ac.mixed_prediction(fc[i], rc[i], lab_post.feature_weight) for i in others]
        out["_w"] = lab_post.feature_weight
    return out


#: The sibling lab (``--sibling``): 20 discs of the rigid_fast tiles (seed 700, cached in experiments/cache), a
#: physics of the rigid family other than the rigid source's rigid_limit.
SIBLING = ("tilelink_rigid_fast", 20, 700)


def load_sibling(executor: str) -> Lab:
    """The sibling lab (:data:`SIBLING`) with every member's readings and its hump features."""
    from plate_env.build.eval_sets import EvalSet, run_eval_set
    from plate_env.run.executor import BackendSpec

    es = EvalSet(SIBLING[0], SIBLING[1], SIBLING[2], (3.0,))
    tables = run_eval_set(es, lambda _: BackendSpec.of("tilelink", model="rigid_fast"), executor,
                          cache_dir=common.CACHE)[3.0]
    fm, _ = common.all_members()
    return Lab("rigidfast", np.array([o.omega_n for o in es.objects()]), common.readings_of("rigidfast", tables, fm),
               common.features_of(tables))


def study(args) -> dict:
    data, fams = load_sources(args.executor)
    # --sibling: what an in-class prior buys, NOT a left-out measurement: the rigid_fast lab teaches every source's
    # feature prior (the rigid source's included; the readings map's priors are unchanged)
    sibling = [load_sibling(args.executor)] if args.sibling else []
    res: dict = {"command": "python " + " ".join(sys.argv), "commit": common.git_commit(dirty=False),
                 "draws": args.draws, "seed": args.seed, "log_sd": args.log_sd, "ks": list(args.ks),
                 "methods": list(args.methods), "feature_prior": args.feature_prior, "sibling": bool(args.sibling),
                 "mixture_by": args.mixture_by, "broad_weight": args.broad_weight,
                 "sources": {s: {"objects": int(sum(len(lab.truth) for lab in labs)), "labs": len(labs),
                                 "family": SOURCE_FAMILY[s]} for s, labs in data.items()},
                 "limits": {s: common.information_limit(labs, fams, SOURCE_FAMILY[s]) for s, labs in data.items()},
                 "priors": {}, "by_k": {}, "weights": {}}
    priors = {}
    for s in SOURCES:
        pseudo = [lab for t, labs in data.items() if SOURCE_FAMILY[t] != SOURCE_FAMILY[s] for lab in labs] + sibling
        if args.feature_prior == "mixture":
            fpkg, finfo = common.learn_feat_mixture(pseudo, args.log_sd, args.broad_weight, args.offset_sd,
                                                    tuple(args.slope_sd), args.lab_log_sd, args.mixture_by,
                                                    args.reduced)
        else:
            fprior, finfo = common.learn_feat_prior_wide(pseudo, args.log_sd)
            fpkg = package_prior(fprior)
        oprior, oinfo = common.learn_scatter_prior(s, data, fams, 0.75)
        rprior, rinfo = common.learn_scatter_prior(s, data, fams, args.log_sd)
        priors[s] = {"features": fpkg, "offset": oprior, "readings": rprior}
        res["priors"][s] = {"features": finfo, "offset": oinfo, "readings": rinfo}
    for K in args.ks:
        t0 = time.perf_counter()
        blocks: dict = {m: {} for m in args.methods}
        weights: dict = {}
        for s in args.sources:
            rng = np.random.default_rng([args.seed, K, SOURCES.index(s)])
            per_m: dict = {m: [] for m in args.methods}
            ws = []
            for lab in data[s]:
                n = len(lab.truth)
                if K >= n - 1:
                    continue
                rd, names = common.lab_readings(lab.readings, fams, {SOURCE_FAMILY[s]})
                arr = {m: {k: np.full((n, args.draws), np.nan) for k in common.SCORE_KEYS} for m in args.methods}
                for d in range(args.draws):
                    ref = rng.choice(n, size=K, replace=False)
                    others = [i for i in range(n) if i not in set(ref.tolist())]
                    got = run_draw(lab, ref, others, rd, names, priors[s], args.methods)
                    if "_w" in got:
                        ws.append(got.pop("_w"))
                    for m, preds in got.items():
                        for k, v in common.scores_with_miss(lab.truth[others], preds).items():
                            arr[m][k][others, d] = v
                for m in args.methods:
                    arr[m]["lab"] = np.array([f"{s}/{lab.name}"] * n)
                    per_m[m].append(arr[m])
            for m in args.methods:
                if per_m[m]:
                    blocks[m][s] = {k: np.concatenate([b[k] for b in per_m[m]]) for k in per_m[m][0]}
            if ws:
                weights[s] = {"mean": float(np.mean(ws)), "median": float(np.median(ws))}
        byk: dict = {}
        for m in args.methods:
            brng = np.random.default_rng([args.seed, K, 99, METHODS.index(m)])
            byk[m] = {"pooled": common.summarize(list(blocks[m].values()), brng, args.n_boot, common.STATS_MISS),
                      **{s: common.summarize([b], brng, args.n_boot, common.STATS_MISS) for s, b in blocks[m].items()}}
        res["by_k"][str(K)] = byk
        res["weights"][str(K)] = weights
        print(f"K = {K} ({time.perf_counter() - t0:.0f} s)", {m: {s: (round(v["median_error"]["value"], 3),
                                                                     round(v["coverage95"]["value"], 3),
                                                                     round(v["width95"]["value"], 2))
                                                                 for s, v in byk[m].items()} for m in byk},
              flush=True)
    return res


# --------------------------------------------------------------------------------------------------- report
LABELS = {"offset": "shipped map (readings, offset, scatter sd(log) 0.75)",
          "readings": "readings map, wide scatter prior", "features": "feature line, mixture prior over labs",
          "adaptive": "adaptive: feature line + readings map by LOO evidence"}


def pooled_limit(res: dict) -> float:
    """The information limit of the pooled row: the median over every disc of its source's best 95 % width."""
    w = np.concatenate([np.full(res["sources"][s]["objects"], res["limits"][s]["best"]["width95"])
                        for s in res["sources"]])
    return float(np.median(w))


def write_md(res: dict) -> str:
    c = common.cell
    lines = ["# Calibrated reading: what each reference disc buys (issue 36)", "",
             f"Command: `{res['command']}` at commit {res['commit']}; generated from `calibration_plans.json`. "
             f"{res['draws']} random reference sets per K and lab (seeded); every other disc of the lab scored; "
             "statistics over every (disc, draw) pair, brackets 95 % bootstrap (labs, then discs). A disc without "
             "an estimate counts as a miss in '95 % coverage' and is left out of 'given an estimate'. Each physics "
             "family left out in turn: a lab's own family is never a member of its forward model and never teaches "
             "its priors.", "",
             "Information limit: " + INFORMATION_LIMIT, "",
             "The feature line's prior (`features`, `adaptive`): " + (
                 "one broad normal over the other families' labs." if res.get("feature_prior") == "broad" else
                 "a mixture over the other families' labs (`common.learn_feat_mixture`): the broad normal (weight "
                 f"{res.get('broad_weight', 0.5):g}) and one component per "
                 f"{'physics family (its labs pooled)' if res.get('mixture_by', 'lab') == 'family' else 'lab'}, "
                 "the references' marginal likelihood reweighting them.")
             + (" **--sibling: the rigid_fast lab teaches every source's feature prior, the rigid source's too: not a "
                "left-out measurement.**" if res.get("sibling") else ""), "",
             "Sources: " + "; ".join(f"`{s}` {v['objects']} discs in {v['labs']} lab(s) (family {v['family']})"
                                     for s, v in res["sources"].items()) + ".", "",
             "## Information limit per source", "",
             "| source | feature line: sd (median error, discs fitted) | readings map: sd (median error) | best: "
             "95 % width |", "|---|---|---|---|"]
    for s, lim in res["limits"].items():
        f, r = lim.get("features"), lim["readings"]
        fs = f"{f['sd']:.3f} ({f['median_error']:.1%}, {f['n']} of {f['of']})" if f else "-"
        lines.append(f"| {s} | {fs} | {r['sd']:.3f} ({r['median_error']:.1%}) | {lim['best']['width95']:.0%} "
                     f"({lim['best']['map']}) |")
    lines.append(f"| pooled (median over discs) | | | {pooled_limit(res):.0%} |")
    k3 = res["by_k"].get("3", {})
    lines += ["", "## Against the targets at K = 3 (median error / 95 % coverage / median 95 % width)", "",
              f"Targets: pooled width <= {TARGET_WIDTH:.0%} and median error <= {TARGET_ERROR:.0%}; 95 % coverage "
              f"{COVERAGE_BAND[0]:.2f}-{COVERAGE_BAND[1]:.2f} at K = 1, 3, 5; width <= {LINED_UP_WIDTH:.0%} where "
              f"the references line up (limit sd <= {LINED_UP_SD:g}: "
              + (", ".join(s for s, lim in res["limits"].items() if lim["best"]["sd"] <= LINED_UP_SD) or "none")
              + ").", "",
              "| method | pooled | " + " | ".join(res["sources"]) + " | 95 % coverage at K = 1 / 3 / 5 (pooled) |",
              "|---|---|" + "---|" * len(res["sources"]) + "---|"]
    lim_cells = [f"{pooled_limit(res):.0%}"] + [f"{res['limits'][s]['best']['width95']:.0%}" for s in res["sources"]]
    lines.append("| information limit (width) | " + " | ".join(lim_cells) + " | |")
    for m, byk in k3.items():
        cells = []
        for s in ["pooled", *res["sources"]]:
            st = byk.get(s)
            cells.append("-" if st is None else f"{st['median_error']['value']:.1%} / {st['coverage95']['value']:.2f}"
                         f" / {st['width95']['value']:.0%}")
        cov = " / ".join(f"{res['by_k'][k][m]['pooled']['coverage95']['value']:.2f}" for k in ("1", "3", "5")
                         if k in res["by_k"])
        lines.append(f"| `{m}` | " + " | ".join(cells) + f" | {cov} |")
    for m in res["methods"]:
        lines += ["", f"## `{m}`: {LABELS[m]}", "",
                  "| K | source | no estimate | median error | 95 % coverage | 95 % coverage given an estimate | "
                  "median 95 % width | information limit: 95 % width |", "|---|---|---|---|---|---|---|---|"]
        for k, byk in res["by_k"].items():
            for s, st in byk[m].items():
                lim = f"{pooled_limit(res):.0%}" if s == "pooled" else f"{res['limits'][s]['best']['width95']:.0%}"
                lines.append(f"| {k} | {s} | {st['no_estimate']['value']:.0%} | {c(st['median_error'], 100, 1)} | "
                             f"{c(st['coverage95'], 1, 2, '')} | {c(st['coverage95_given'], 1, 2, '')} | "
                             f"{c(st['width95'])} | {lim} |")
    if any(res["weights"].values()):
        lines += ["", "Adaptive: mean weight of the feature line (the readings map has the rest) per K: "
                  + "; ".join(f"K = {k}: " + ", ".join(f"{s} {v['mean']:.2f}" for s, v in w.items())
                              for k, w in res["weights"].items()) + "."]
    lines += ["", "Priors (learned from the labs of the other families): " + "; ".join(
        f"{s}: feature line {common.prior_text(p['features'])}; readings {common.prior_text(p['readings'])}"
        for s, p in res["priors"].items()), ""]
    return "\n".join(lines) + "\n"


INFORMATION_LIMIT = ("each source's discs fitted in-sample by the best of the feature line and the readings map, "
                     "every disc a reference and scored (no reference budget): the narrowest calibrated 95 % width "
                     "these data could support, e^1.96sd - e^-1.96sd (`common.information_limit`). In-sample, so "
                     "below what any held-out method reaches.")


def plot(res: dict, out: Path = IMG) -> None:
    """Median 95 % width and 95 % coverage against K, per source, of the shipped map and the adaptive candidate,
    the information limit dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ks = [int(k) for k in res["by_k"]]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    srcs = [*res["sources"], "pooled"]
    colors = dict(zip(srcs, plt.rcParams["axes.prop_cycle"].by_key()["color"], strict=False))
    for m, style in (("offset", ":"), ("adaptive", "-")):
        if m not in res["methods"]:
            continue
        for s in srcs:
            w = [100 * res["by_k"][str(k)][m][s]["width95"]["value"] for k in ks]
            cv = [res["by_k"][str(k)][m][s]["coverage95"]["value"] for k in ks]
            lab = f"{s} ({'shipped' if m == 'offset' else 'adaptive'})"
            a1.plot(ks, w, style, marker="o", color=colors[s], label=lab)
            a2.plot(ks, cv, style, marker="o", color=colors[s], label=lab)
    for s in srcs:
        lim = pooled_limit(res) if s == "pooled" else res["limits"][s]["best"]["width95"]
        a1.axhline(100 * lim, ls="--", lw=0.8, color=colors[s])
    a1.set_yscale("log")
    a1.set_xlabel("reference discs K")
    a1.set_ylabel("median 95 % width (% of omega_n)")
    a1.set_title("width (dashed: information limit)")
    a2.axhspan(*COVERAGE_BAND, color="0.9")
    a2.set_xlabel("reference discs K")
    a2.set_ylabel("95 % coverage (misses counted)")
    a2.set_title("coverage (grey: 0.90-0.98)")
    a2.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def shipped_priors(args) -> dict:
    """The priors a real lab's calibration ships with: learned from the labs of EVERY family (nothing is left out:
    a real plate is none of them), each lab read through the members of the other families (the readings map's
    scatter) or fitted by its own feature line; written into the JSON as ``shipped_priors`` (the constants of
    ``plate_env.identify.adaptive_calibration`` cite them)."""
    data, fams = load_sources(args.executor)
    labs = [lab for ls in data.values() for lab in ls]
    fprior, finfo = common.learn_feat_prior_wide(labs, args.log_sd)
    mix, minfo = common.learn_feat_mixture(labs, args.log_sd, args.broad_weight, args.offset_sd, tuple(args.slope_sd),
                                           args.lab_log_sd, args.mixture_by)
    found = {}
    from plate_env.identify.lab_calibration import ScatterPrior, fit_lab

    for s, ls in data.items():
        for lab in ls:
            rd, names = common.lab_readings(lab.readings, fams, {SOURCE_FAMILY[s]})
            found[lab.name] = fit_lab(rd, np.log(lab.truth), names, ScatterPrior(0.2, 5.0)).summary()["sigma_mean"]
    med = float(np.exp(np.mean(np.log(list(found.values())))))
    return {"command": "python " + " ".join(sys.argv), "commit": common.git_commit(dirty=False),
            "features": {**finfo, "c0": fprior.c0.tolist()}, "feature_mixture": {**minfo, **mix.to_json()},
            "readings": {"pseudo_labs": found, "median": med, "log_sd": args.log_sd}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("stage", choices=("study", "md", "plot", "priors"))
    ap.add_argument("--draws", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--log-sd", type=float, default=1.5, help="spread (sd of log sigma) of the wide scatter priors")
    ap.add_argument("--n-boot", type=int, default=300)
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--executor", default="inprocess", help="runs the pmlab sweeps when they are not cached")
    ap.add_argument("--feature-prior", default="mixture", choices=("broad", "mixture"),
                    help="the feature line's prior over labs: one broad normal, or a mixture of it (--broad-weight) "
                         "and one component per lab (common.learn_feat_mixture)")
    ap.add_argument("--broad-weight", type=float, default=0.5)
    ap.add_argument("--reduced", type=float, default=0.0,
                    help="share of the broad component's weight given to a broad line in log omega_Brmax alone")
    ap.add_argument("--mixture-by", default="lab", choices=("lab", "family"),
                    help="one mixture component per simulated lab, or per physics family (its labs pooled)")
    ap.add_argument("--offset-sd", type=float, default=0.5)
    ap.add_argument("--slope-sd", type=float, nargs=2, default=[0.05, 1.0])
    ap.add_argument("--lab-log-sd", type=float, default=0.75)
    ap.add_argument("--sibling", action="store_true",
                    help="the rigid_fast lab (SIBLING) teaches every source's feature prior, the rigid source's too: "
                         "what a prior that knows the lab's physics class buys (not a left-out measurement)")
    ap.add_argument("--sources", nargs="+", default=list(SOURCES), choices=list(SOURCES))
    ap.add_argument("--tag", default="", help="suffix of the result files (variants)")
    ap.add_argument("--ks", type=int, nargs="+", default=list(KS), help="reference plans (K)")
    args = ap.parse_args()
    path = RESULTS / f"calibration_plans{args.tag}.json"
    if args.stage == "study":
        res = study(args)
        old = json.loads(path.read_text()) if path.exists() else {}
        if "shipped_priors" in old:
            res["shipped_priors"] = old["shipped_priors"]  # its own command and commit
        path.write_text(json.dumps(res, indent=1) + "\n")
    else:
        res = json.loads(path.read_text())
    if args.stage == "priors":
        res["shipped_priors"] = shipped_priors(args)
        path.write_text(json.dumps(res, indent=1) + "\n")
        print(json.dumps(res["shipped_priors"], indent=1))
        return
    if args.stage == "plot":
        plot(res)
        return
    md = write_md(res)
    (RESULTS / f"calibration_plans{args.tag}.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
