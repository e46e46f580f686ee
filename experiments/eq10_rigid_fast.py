"""The faithful physics' Eq. (10) line (tilelink/rigid_fast/3, issue 33): which sweeps make it, and how it compares.

    python experiments/eq10_rigid_fast.py

Two sources of 10-40 Hz (1 Hz) sweeps at 3 deg, B_p 3 mm on ``rigid_fast``, each fitted by the builder's rule
(:func:`plate_env.build.eq10.sweep_line`: first-hump Lorentzian f0, omega_n regressed on it, the friction model):

(a) the calibration objects (9 omega_n x 4 alpha, 36 centred sweeps, 1,116 probes), the point-mass lines' objects,
    simulated by ``python experiments/calibrate.py --physics tilelink --model rigid_fast --amps 3 --executor pool:1``
    into experiments/cache/sweeps_tilelink_rigid_fast.jsonl (about 17 min on one core);
(b) the faithful atlas's committed probes (experiments/cache/atlas_faithful.jsonl, no CPU), its omega_n nodes within
    the calibration objects' range (3.5-33 pi), every alpha node, both repeats: every probe placed on its own (yaw,
    offset), as the atlas was built. The shipped line (``plate-env build calibration eq10``,
    :func:`plate_env.build.eq10.rigid_fast_line`) is this one.

Each line is scored on an independent live set, the faithful forward-model study's test sweeps (20 objects from the
prior, rigid_fast, placed; experiments/cache/eval_tilelink_rigid_fast_A3_s700.jsonl): omega_n from each sweep's f0
through the line against the truth. Reads caches only (a missing probe is an error, not simulated). Writes
experiments/results/eq10_rigid_fast.{json,md}.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from plate_env.build import eval_sets as es_mod
from plate_env.build.atlas_grid import AtlasGrid, grid_probes, run_grid
from plate_env.build.eq10 import RIGID_FAST, RIGID_FAST_AMP_DEG, sweep_line, tilelink_specs
from plate_env.build.eval_sets import EvalSet, run_eval_set
from plate_env.identify.calibration import fit_calibration, load_calibrations, paper_calibration
from plate_env.identify.fitting import fit_results
from plate_env.run.sweeps import backend_tag, load_cache, run_cached, spec_key

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "experiments" / "cache"
RESULTS = ROOT / "experiments" / "results"
GRID = ROOT / "plate_env" / "data" / "grids" / "faithful.json"
ATLAS_CACHE = CACHE / "atlas_faithful.jsonl"
SWEEPS_A = CACHE / "sweeps_tilelink_rigid_fast.jsonl"
TEST = EvalSet("tilelink_rigid_fast", 20, 700, (3.0,))
#: The converged rigid limit's line (the lab line's rigid family as shipped, experiments/results/eq10_rebuild.md).
RIGID_LIMIT_PI = (5.154574, -118.6436)


def _complete(specs, cache: Path) -> None:
    tag, done = backend_tag(RIGID_FAST), load_cache(cache) if cache.is_file() else {}
    if n := sum(spec_key(tag, s) not in done for s in specs):
        raise SystemExit(f"{cache} lacks {n} of {len(specs)} probes: this script reads caches only")


def source_a():
    specs = tilelink_specs(RIGID_FAST_AMP_DEG)
    _complete(specs, SWEEPS_A)
    res = run_cached(RIGID_FAST, specs, SWEEPS_A, progress=False)
    n = len(es_mod.SWEEP_F_HZ)
    sweeps = [res[i * n:(i + 1) * n] for i in range(len(res) // n)]
    objs = es_mod.objects(es_mod.CALIBRATION_OMEGAS_PI, es_mod.CALIBRATION_ALPHAS_DEG)
    pts = [(f.f0, o.omega_n) for o, sw in zip(objs, sweeps, strict=True) if (f := fit_results(sw)).ok]
    return sweep_line(sweeps, RIGID_FAST_AMP_DEG, None, "tilelink", "rigid_fast"), sweeps, pts


#: A first-hump f0 above this (Hz) is a lone stable probe past the instability band (no calibration object's hump is
#: there: the clean sweeps' f0 are 22.7-29.0 Hz); the lines without such sweeps, for the reading only.
PAST_BAND_HZ = 30.0


def without_past_band(pts) -> dict:
    kept = [(f0, w) for f0, w, *_ in pts if f0 <= PAST_BAND_HZ]
    cal = fit_calibration([k[0] for k in kept], [k[1] for k in kept], "tilelink", "rigid_fast", RIGID_FAST_AMP_DEG)
    return {**line_row(cal), "dropped_f0_hz": sorted(round(f0, 1) for f0, *_ in pts if f0 > PAST_BAND_HZ)}


def source_b():
    grid = AtlasGrid.from_json(GRID)
    _complete(grid_probes(grid, 2, np.random.default_rng(0))[1], ATLAS_CACHE)
    res = run_grid(RIGID_FAST, grid, 2, 0, ATLAS_CACHE, progress=False)
    ia = grid.a_p_deg.index(RIGID_FAST_AMP_DEG)
    lo, hi = min(es_mod.CALIBRATION_OMEGAS_PI), max(es_mod.CALIBRATION_OMEGAS_PI)
    pts, total, sweeps = [], 0, []
    for iw, w_pi in enumerate(grid.omega_n_pi):
        if not lo <= w_pi <= hi:
            continue
        for ial, a in enumerate(grid.alpha_deg):
            for r in range(2):
                total += 1
                sw = list(res[:, ia, iw, ial, r])
                sweeps.append(sw)
                if (fit := fit_results(sw)).ok:
                    pts.append((fit.f0, w_pi * math.pi, fit.omega_max, math.radians(a)))
    f0, w, wm, al = (list(x) for x in zip(*pts, strict=True))
    cal = fit_calibration(f0, w, "tilelink", "rigid_fast", RIGID_FAST_AMP_DEG, omega_max_deg_s=wm, alpha_rad=al,
                          provenance={"sweeps_fitted": len(pts), "sweeps_total": total})
    return cal, pts, sweeps


def unstable_share(sweeps) -> float:
    return float(np.mean([r.unstable for sw in sweeps for r in sw]))


def scored(cal, test) -> dict:
    """omega_n through ``cal`` from the test set's fitted f0 against the truth (rad/s -> pi rad/s, relative)."""
    err = np.array([(cal.omega_n(f0) - w) / math.pi for f0, w in test])
    rel = np.array([abs(cal.omega_n(f0) - w) / w for f0, w in test])
    return {"n": len(test), "rmse_pi": float(np.sqrt(np.mean(err ** 2))), "median_abs_pi": float(np.median(abs(err))),
            "median_rel": float(np.median(rel)), "p90_rel": float(np.quantile(rel, 0.9))}


def line_row(cal) -> dict:
    return {"n": cal.n, "sweeps_total": cal.provenance.get("sweeps_total"), "p1_pi": cal.p1_pi, "q1_pi": cal.q1_pi,
            "p1_se_pi": cal.p1_se / math.pi, "q1_se_pi": cal.q1_se / math.pi, "r2": cal.r2,
            "resid_std_pi": cal.resid_std / math.pi,
            "alpha_resid_deg": math.degrees(cal.alpha_resid_std) if cal.alpha_coef is not None else None}


def main() -> None:
    a, sweeps_a, pts_a = source_a()
    b, pts_b, sweeps_b = source_b()
    tables = run_eval_set(TEST, lambda _n: RIGID_FAST, None, False, cache_dir=CACHE)[3.0]
    test = []
    for o, t in zip(TEST.objects(), tables, strict=True):
        fit = fit_results_table(t)
        if fit.ok:
            test.append((fit.f0, o.omega_n))
    shipped = load_calibrations()
    pm = shipped["tilelink/pointmass/3"]
    paper = paper_calibration(3.0)
    from plate_env.identify.calibration import Calibration

    rl = Calibration("tilelink", "rigid_limit", 3.0, RIGID_LIMIT_PI[0] * math.pi, RIGID_LIMIT_PI[1] * math.pi)
    out = {"command": "python experiments/eq10_rigid_fast.py",
           "a_calibration_objects": {**line_row(a), "unstable_share": unstable_share(sweeps_a),
                                     "test": scored(a, test), "without_past_band": without_past_band(pts_a)},
           "b_atlas_nodes": {**line_row(b), "unstable_share": unstable_share(sweeps_b), "test": scored(b, test),
                             "without_past_band": without_past_band(pts_b)},
           "shipped": {k: line_row(shipped[k]) for k in ("tilelink/rigid_fast/3", "tilelink/pointmass/3")
                       if k in shipped},
           "reference_test": {"paper": scored(paper, test), "rigid_limit": scored(rl, test),
                              "pointmass": scored(pm, test)}}
    (RESULTS / "eq10_rigid_fast.json").write_text(json.dumps(out, indent=1) + "\n")
    (RESULTS / "eq10_rigid_fast.md").write_text(render(out) + "\n")
    print(render(out))


def fit_results_table(t):
    from plate_env.identify.fitting import fit_lorentzian

    return fit_lorentzian(t.f_p_hz, t.omega_b_deg_s, t.stderr_deg_s, t.unstable)


def render(d: dict) -> str:
    a, b = d["a_calibration_objects"], d["b_atlas_nodes"]
    ab, bb = a["without_past_band"], b["without_past_band"]

    def row(name, r, src):
        se = f" ± {r['p1_se_pi']:.2f}" if r.get("p1_se_pi") else ""
        qse = f" ± {r['q1_se_pi']:.1f}" if r.get("q1_se_pi") else ""
        return (f"| {name} | {src} | {r['p1_pi']:.2f}{se} | {r['q1_pi']:.1f}{qse} | "
                f"{r['r2']:.3f} | {r['resid_std_pi']:.2f} |")
    t = ["| line | sweeps | p1 [pi rad/s per Hz] | q1 [pi rad/s] | R^2 | residual std [pi rad/s] |",
         "|---|---|---|---|---|---|",
         row("(a) rigid_fast, calibration objects, centred", a, f"{a['n']} of {a['sweeps_total']} fitted"),
         row("(b) rigid_fast, atlas nodes 3.7-30.6 pi (shipped)", b, f"{b['n']} of {b['sweeps_total']} fitted"),
         "| the paper, Eq. (10) at 3 deg | measured | 5.30 | -121.62 | 0.99 | - |",
         f"| rigid_limit (lab line's rigid family, shipped) | 18 of 20 prior objects, placed | "
         f"{RIGID_LIMIT_PI[0]:.2f} | {RIGID_LIMIT_PI[1]:.1f} | - | - |"]
    if pm := d["shipped"].get("tilelink/pointmass/3"):
        t.append(row("tilelink/pointmass/3 (shipped)", {**pm}, f"{pm['n']} of {pm['sweeps_total']} fitted"))
    s = ["| line | median abs error [pi rad/s] | RMS [pi rad/s] | median rel. error | p90 rel. error |",
         "|---|---|---|---|---|"]
    for name, r in (("(a) calibration objects", a["test"]), ("(b) atlas nodes", b["test"]),
                    *((f"{k}", v) for k, v in d["reference_test"].items())):
        s.append(f"| {name} | {r['median_abs_pi']:.2f} | {r['rmse_pi']:.2f} | {100 * r['median_rel']:.1f} % | "
                 f"{100 * r['p90_rel']:.1f} % |")
    return "\n".join([
        "# Eq. (10) on the faithful physics: tilelink/rigid_fast/3", "",
        f"`{d['command']}` (reads caches only). Two sources of sweeps on rigid_fast, both at 3 deg, 10-40 Hz at "
        "1 Hz, B_p 3 mm, 1 s windows, fitted by the builder's rule (first-hump Lorentzian f0, omega_n regressed "
        "on it, the friction model): (a) the 36 calibration objects of the point-mass lines, centred, simulated "
        "by `python experiments/calibrate.py --physics tilelink --model rigid_fast --amps 3 --executor pool:1` "
        "(1,116 probes, 17 min on one core; experiments/cache/sweeps_tilelink_rigid_fast.jsonl); (b) the faithful "
        "atlas's committed probes (experiments/cache/atlas_faithful.jsonl, no CPU), its omega_n nodes in the "
        "calibration objects' range (3.7-30.6 pi) x 5 alpha (26-64 deg) x 2 repeats, every probe placed on its "
        "own. The shipped line tilelink/rigid_fast/3 is (b): `plate-env build calibration eq10` reads those "
        "3,720 probes as an input (frozen in plate_env/data/inputs/atlas_faithful.jsonl, records of the "
        "committed cache) and never simulates them.", "",
        *t, "",
        f"Unstable probes: (a) {100 * a['unstable_share']:.0f} %, (b) {100 * b['unstable_share']:.0f} %. "
        f"Friction model residual: (a) {a['alpha_resid_deg']:.1f} deg, (b) {b['alpha_resid_deg']:.1f} deg "
        f"(alphas 30-56.3 and 26-64 deg).", "",
        "## Which source, and why", "",
        f"(b), the shipped one: with the same fit rule it makes the better line on every measure here (R^2 "
        f"{b['r2']:.2f} against {a['r2']:.2f}, residual {b['resid_std_pi']:.1f} against {a['resid_std_pi']:.1f} pi "
        f"rad/s, median error on the independent set {100 * b['test']['median_rel']:.0f} % against "
        f"{100 * a['test']['median_rel']:.0f} %), costs no CPU, and its probes are placed as the env's episodes' "
        "are ((a)'s are centred). Neither is of the point-mass line's quality (R^2 0.91): on rigid tiles the hump "
        "runs into the instability band (about half the probes of a 3-deg sweep end unstable, from ~22-30 Hz up), "
        "and the first-hump rule, tuned on the point mass, bridges that band while omega_B still rises into it, so "
        f"a lone stable probe past it becomes the 'peak': f0 {ab['dropped_f0_hz']} Hz in (a), "
        f"{bb['dropped_f0_hz']} Hz in (b), where every other sweep's f0 is below {PAST_BAND_HZ:g} Hz. As the true "
        "f0 spans only ~23-29 Hz over the whole omega_n range, these few sweeps pull the least-squares slope far "
        f"below the rigid limit's. Without them (for this reading only): (a) p1 {ab['p1_pi']:.2f}, q1 "
        f"{ab['q1_pi']:.1f}, R^2 {ab['r2']:.3f}, residual {ab['resid_std_pi']:.2f} pi rad/s ({ab['n']} sweeps); "
        f"(b) p1 {bb['p1_pi']:.2f}, q1 {bb['q1_pi']:.1f}, R^2 {bb['r2']:.3f}, residual {bb['resid_std_pi']:.2f} "
        f"({bb['n']} sweeps): the centred design is the cleaner one, but with 31 sweeps two strays ruin it, with "
        "108 one stray costs less. The fix is a first-hump rule aware of the instability band, for the Lorentz "
        "estimator and the line together (a rule for the line alone would read another f0 than the estimator "
        "reads); not done here.", "",
        f"## Against an independent live set ({a['test']['n']} of 20 fitted)", "",
        "The faithful forward-model study's test sweeps (20 prior objects, rigid_fast, each probe placed, 3 deg; "
        "experiments/cache/eval_tilelink_rigid_fast_A3_s700.jsonl): omega_n through each line from the sweep's "
        "first-hump f0, against the truth.", "",
        *s])


if __name__ == "__main__":
    main()
