"""Issue 36 prototype (PARTIAL, research in progress): a feature-line calibration whose scatter adapts to the lab.

    python experiments/calibration_adaptive.py [--draws 8] [--seed 0] [--log-sd 1.5] [--nu inf] [--features lorentz]

What differs from ``calibration_study.py``'s ``features`` method (whose scatter prior, learned from the labs of one
other physics, sits at their scatter with sd(log) 0.75, so a lab is read as if it were like them):

- the hierarchical prior over labs is learned from every lab of every *other* physics family (pseudo-labs: each
  cached source split into labs of ``--lab-n`` discs), the scatter prior log-normal around their geometric mean
  with a spread at least ``--log-sd`` (default 1.5: wide, so the references' own residuals decide the scatter);
- the predictive integrates the scatter over its posterior on a grid (a scale mixture of normals: heavy tails,
  Student-t-like, where the references are few); ``--nu`` makes each normal a Student-t;
- ``--features raw``: the largest stable probe instead of the Lorentzian fit (defined on every sweep);
- the information limit of every source (its in-sample least-squares scatter of log omega_n on (f0, log
  omega_Brmax), all discs) is printed beside its numbers.

Sources: the cached sweeps of ``forward_models.py`` (``pointmass`` per-disc nuisance s400, ``rigid`` rigid_limit
s100, ``pybullet`` s600); each physics family left out in turn (its labs never teach the prior). Only the feature
line is measured here: the member-likelihood readings (``calibration_study.py``'s ``offset``) need readings that are
not cached on this machine (not computed in this session: the CPU was shared). Writes
``experiments/results/calibration_adaptive{--tag}.{json,md}``; status and findings:
``experiments/results/calibration_adaptive_notes.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import common
import numpy as np

RESULTS = Path("experiments/results")
KS = (1, 2, 3, 5, 8)
SOURCES = ("pointmass", "rigid", "pybullet")


def raw_features_of(tables) -> np.ndarray:
    """Each sweep's hump read without a fit, in :func:`calibration_study.features_of`'s columns (ok, f0, b, omega_max,
    f0 stderr): the stable probe with the largest omega_B, its frequency refined by a parabola through it and its two
    neighbours (when both are stable), b and the stderr NaN. Defined whenever one stable probe rotates."""
    out = np.full((len(tables), 5), np.nan)
    for i, t in enumerate(tables):
        f, w = np.asarray(t.f_p_hz, float), np.where(np.asarray(t.unstable), np.nan, np.asarray(t.omega_b_deg_s, float))
        out[i, 0] = 0.0
        if not np.isfinite(w).any() or np.nanmax(w) <= 0:
            continue
        j = int(np.nanargmax(w))
        f0, wm = f[j], w[j]
        if 0 < j < len(w) - 1 and np.isfinite(w[j - 1]) and np.isfinite(w[j + 1]):
            den = w[j - 1] - 2 * w[j] + w[j + 1]
            if den < 0:
                d = 0.5 * (w[j - 1] - w[j + 1]) / den
                f0 = f[j] + d * 0.5 * (f[j + 1] - f[j - 1])
                wm = w[j] - 0.25 * (w[j - 1] - w[j + 1]) * d
        out[i, 0], out[i, 1], out[i, 3] = 1.0, f0, wm
    return out


FEATURES = {"lorentz": common.features_of, "raw": raw_features_of}


def load(src: str, lab_n: int, features: str = "lorentz") -> list[common.Lab]:
    """The cached sweeps of ``src`` as labs of ``lab_n`` discs (consecutive objects; one lab when fewer), with the
    hump features ``features`` (:data:`FEATURES`)."""
    truth, tables = common.source_data(src, None, None)
    truth = np.asarray(truth)
    feats = FEATURES[features](tables)
    n = len(truth)
    n_labs = max(1, n // lab_n)
    edges = np.linspace(0, n, n_labs + 1).astype(int)
    return [common.Lab(f"{src}{j}" if n_labs > 1 else src, truth[a:b], [], feats[a:b])
            for j, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True))]


def oracle(labs: list[common.Lab]) -> dict:
    """The information limit of a source: least squares of log omega_n on (1, f0, log omega_Brmax) over ALL its
    discs (labs pooled), in-sample residual sd and median abs error."""
    F = np.concatenate([lab.features for lab in labs])
    y = np.log(np.concatenate([lab.truth for lab in labs]))
    ok = F[:, 0] == 1
    x = common.feat_x(F[ok])
    beta, *_ = np.linalg.lstsq(x, y[ok], rcond=None)
    r = y[ok] - x @ beta
    return {"n": int(ok.sum()), "of": int(ok.size), "sd": float(np.sqrt(np.mean(r ** 2))),
            "median_error": float(np.median(np.abs(np.expm1(r))))}


def feat_predict_t(post, f_row: np.ndarray, nu: float):
    """:func:`calibration_study.feat_predict` with each scatter's normal replaced by a Student-t of ``nu`` degrees of
    freedom and the same scale (nu = inf: the normal): heavier tails for sweeps whose features are outliers."""
    from scipy.stats import t as student_t

    if not math.isfinite(nu):
        return common.feat_predict(post, f_row)
    from plate_env.identify.lab_calibration import Prediction

    if f_row[0] != 1:
        return Prediction(False, reason="no Lorentzian fit")
    wt, parts = post
    x = common.feat_x(f_row[None])[0]
    cdf = np.zeros_like(common.FEAT_Y)
    for w, sg, (mn, cn) in zip(wt, common.FEAT_SIGMAS, parts, strict=True):
        if w >= 1e-8:
            cdf += w * student_t.cdf(common.FEAT_Y, nu, x @ mn, math.sqrt(sg ** 2 + x @ cn @ x))
    cdf /= cdf[-1]

    def q(level: float) -> float:
        return float(math.exp(np.interp(level, cdf, common.FEAT_Y)))

    return Prediction(True, q(0.5), (q(0.16), q(0.84)), (q(0.025), q(0.975)))


def feat_fit_ev(prior: common.FeatPrior, F: np.ndarray, y: np.ndarray):
    """:func:`calibration_study.feat_fit` and the references' log marginal likelihood under ``prior`` (the scatter
    prior normalised on the grid); 0 without a reference that has features."""
    wt, parts = common.feat_fit(prior, F, y)
    ok = F[:, 0] == 1
    x, yy = common.feat_x(F[ok]), y[ok]
    lp = -0.5 * ((np.log(common.FEAT_SIGMAS) - math.log(prior.sigma_median)) / prior.log_sd) ** 2
    lp -= np.logaddexp.reduce(lp)
    for j, sg in enumerate(common.FEAT_SIGMAS):
        cov_y = sg ** 2 * np.eye(len(yy)) + x @ prior.c0 @ x.T
        r = yy - x @ prior.m0
        _, logdet = np.linalg.slogdet(cov_y)
        lp[j] += -0.5 * (logdet + r @ np.linalg.solve(cov_y, r) + len(yy) * math.log(2 * math.pi))
    return (wt, parts), float(np.logaddexp.reduce(lp))


def offset_only(prior: common.FeatPrior) -> common.FeatPrior:
    """The same prior with the slopes held at their prior means (sd 1e-4): only the intercept and the scatter are
    learned from the references."""
    c0 = prior.c0.copy()
    c0[1:, :] = 0.0
    c0[:, 1:] = 0.0
    c0[1, 1] = c0[2, 2] = 1e-8
    return common.FeatPrior(prior.m0, c0, prior.sigma_median, prior.log_sd)


def bma_predict(fits, f_row: np.ndarray, nu: float):
    """The candidates' predictives averaged by their evidence (``fits``: [(post, log_ev)])."""
    from plate_env.identify.lab_calibration import Prediction

    preds = [(feat_predict_t(post, f_row, nu), lev) for post, lev in fits]
    if not preds[0][0].ok:
        return preds[0][0]
    lev = np.array([lv for _, lv in preds])
    w = np.exp(lev - lev.max())
    w /= w.sum()
    # mixture quantiles from each candidate's own quantiles: interpolate a CDF through its 5 quantile points (log)
    grid = common.FEAT_Y
    cdf = np.zeros_like(grid)
    for (p, _), wi in zip(preds, w, strict=True):
        qs = np.log([p.ci95[0], p.ci68[0], p.omega_n, p.ci68[1], p.ci95[1]])
        cdf += wi * np.interp(grid, qs, [0.025, 0.16, 0.5, 0.84, 0.975], left=0.0, right=1.0)

    def q(level: float) -> float:
        return float(math.exp(np.interp(level, cdf, grid)))

    return Prediction(True, q(0.5), (q(0.16), q(0.84)), (q(0.025), q(0.975)))


def run(args) -> dict:
    data = {s: load(s, args.lab_n, args.features) for s in args.sources}
    out: dict = {"command": "python " + " ".join(sys.argv), "commit": common.git_commit(dirty=False),
                 "draws": args.draws,
                 "seed": args.seed, "log_sd": args.log_sd, "lab_n": args.lab_n,
                 "features": args.features, "nu": args.nu, "bma": args.bma,
                 "oracle": {s: oracle(labs) for s, labs in data.items()}, "priors": {}, "by_k": {}}
    priors = {}
    for s in args.sources:
        pseudo = [lab for t, labs in data.items() if common.SOURCE_FAMILY[t] != common.SOURCE_FAMILY[s] for lab in labs]
        priors[s], out["priors"][s] = common.learn_feat_prior_wide(pseudo, args.log_sd)
    for K in KS:
        blocks = {}
        for s in args.sources:
            rng = np.random.default_rng([args.seed, K, SOURCES.index(s)])
            bl = []
            for lab in data[s]:
                n = len(lab.truth)
                res = {k: np.full((n, args.draws), np.nan) for k in common.SCORE_KEYS}
                res["lab"] = np.array([f"{s}/{lab.name}"] * n)
                if K >= n - 1:
                    continue
                for d in range(args.draws):
                    ref = rng.choice(n, size=K, replace=False)
                    others = [i for i in range(n) if i not in set(ref.tolist())]
                    y = np.log(lab.truth[ref])
                    if args.bma:
                        fits = [feat_fit_ev(pr, lab.features[ref], y) for pr in (priors[s], offset_only(priors[s]))]
                        preds = [bma_predict(fits, lab.features[i], args.nu) for i in others]
                    else:
                        post = common.feat_fit(priors[s], lab.features[ref], y)
                        preds = [feat_predict_t(post, lab.features[i], args.nu) for i in others]
                    for k, v in common.scores_with_miss(lab.truth[others], preds).items():
                        res[k][others, d] = v
                bl.append(res)
            if bl:
                blocks[s] = {k: np.concatenate([b[k] for b in bl]) for k in bl[0]}
        brng = np.random.default_rng([args.seed, K, 99])
        out["by_k"][str(K)] = {"pooled": common.summarize(list(blocks.values()), brng, args.n_boot, common.STATS_MISS),
                               **{s: common.summarize([b], brng, args.n_boot, common.STATS_MISS)
                                  for s, b in blocks.items()}}
        print(K, {k: (round(v["median_error"]["value"], 3), round(v["coverage95"]["value"], 3),
                      round(v["width95"]["value"], 2)) for k, v in out["by_k"][str(K)].items()}, flush=True)
    return out


def write_md(res: dict) -> str:
    lines = ["# Issue 36 prototype: feature line with a lab-adaptive scatter (PARTIAL)", "",
             f"Command: `{res['command']}` at commit {res['commit']}. Generated from `calibration_adaptive.json`. "
             "Each physics family left out in turn (its labs never teach the prior); statistics over every (object, "
             "draw) pair, a disc without a Lorentzian fit scored as a miss (no estimate). Information limit: the "
             "source's in-sample least-squares scatter of log omega_n on (1, f0, log omega_Brmax), all its discs "
             "(a 95 % width of about 4 x sd). Feature line only: the readings map is not measured here.", "",
             "Coverage 'given an estimate' leaves out the discs without hump features (share in 'no estimate').", "",
             "| K | source | information limit: sd (median error) | no estimate | median error | 68 % coverage | "
             "95 % coverage | 95 % coverage given an estimate | median 95 % width |",
             "|---|---|---|---|---|---|---|---|---|"]
    for k, byk in res["by_k"].items():
        for s, st in byk.items():
            o = res["oracle"].get(s)
            lim = f"{o['sd']:.3f} ({o['median_error']:.1%}; {o['n']} of {o['of']} fitted)" if o else "-"
            lines.append(f"| {k} | {s} | {lim} | {st['no_estimate']['value']:.0%} | "
                         f"{common.cell(st['median_error'], 100, 1)} | {common.cell(st['coverage68'], 1, 2, '')} | "
                         f"{common.cell(st['coverage95'], 1, 2, '')} | "
                         f"{common.cell(st['coverage95_given'], 1, 2, '')} | "
                         f"{common.cell(st['width95'])} |")
    lines += ["", "Priors: " + "; ".join(f"{s}: {common.prior_text(p)}" for s, p in res["priors"].items()), ""]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--draws", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--log-sd", type=float, default=1.5)
    ap.add_argument("--lab-n", type=int, default=20)
    ap.add_argument("--n-boot", type=int, default=300)
    ap.add_argument("--sources", nargs="+", default=list(SOURCES), choices=list(SOURCES))
    ap.add_argument("--features", default="lorentz", choices=list(FEATURES),
                    help="the hump features: the Eq. 9 Lorentzian fit, or the largest stable probe (raw)")
    ap.add_argument("--nu", type=float, default=math.inf, help="the predictive's degrees of freedom per scatter")
    ap.add_argument("--bma", action="store_true", help="average the full line and the intercept-only line (slopes "
                    "at the prior's) by the references' marginal likelihood")
    ap.add_argument("--tag", default="", help="suffix of the result files (variants)")
    args = ap.parse_args()
    res = run(args)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"calibration_adaptive{args.tag}.json").write_text(json.dumps(res, indent=1) + "\n")
    md = write_md(res)
    (RESULTS / f"calibration_adaptive{args.tag}.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
