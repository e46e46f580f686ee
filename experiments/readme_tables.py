"""The measured tables of README.md and docs/*.md, rendered from their result files (the source of truth).

    python experiments/readme_tables.py            # rewrite every table between its markers
    python experiments/readme_tables.py --check    # exit 1 and name each table that differs from its result file

A table lives between ``<!-- table: NAME -->`` and ``<!-- /table -->``; NAME is a key of ``TABLES``, whose entry
names the JSON file in experiments/results/ it is rendered from (env_info: plate_env/env/info.py, the env's info
schema). Nothing here measures anything: it only formats numbers that experiments/*.py wrote (each file's own script
regenerates it), so a number in the docs cannot drift from its result. tests/test_readme.py runs the check.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
#: The markdown files whose tables are checked: the README and every docs page.
PAGES = ("README.md", "docs")
MARKER = re.compile(r"<!-- table: (?P<name>[\w.-]+) -->\n(?P<body>.*?)<!-- /table -->", re.S)


# ------------------------------------------------------------------------------------------------ formatting
def _stat(d: dict, scale: float = 1.0, digits: int = 1, unit: str = "", interval: bool = True) -> str:
    """``value [lo, hi]`` of a ``{"value", "ci95"}`` statistic (plate_env.scoring.Stat.to_dict). ``None`` is a
    non-finite number written as JSON's null (``plate-env bench --json`` lists them under "non_finite"): an
    infinite error or width."""
    def num(x: float | None) -> str:
        return "inf" if x is None or math.isinf(x) else f"{x * scale:.{digits}f}"
    if not interval:
        return f"{num(d['value'])}{unit}"
    lo, hi = d["ci95"]
    return f"{num(d['value'])}{unit} [{num(lo)}, {num(hi)}]"


def _dist(sigma: float, nu: float) -> str:
    """A discrepancy's law and scale: normal (nu infinite), Cauchy (nu 1) or Student-t."""
    name = "normal" if math.isinf(nu) else "Cauchy" if nu == 1 else f"t({nu:g})"
    return f"{name} {sigma:.2f}"


def _table(head: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _load(name: str) -> dict:
    return json.loads((RESULTS / name).read_text())


def _score_cells(s: dict, interval_width: bool = False) -> list[str]:
    """median error, p90, 68 % and 95 % coverage, median 95 % width of a plate_env.scoring.Scores dict."""
    return [_stat(s["median_error"], 100, 1, " %"), _stat(s["p90_error"], 100, 1, " %"),
            _stat(s["coverage68"], 1, 2), _stat(s["coverage95"], 1, 2),
            _stat(s["width95"], 100, 0, " %", interval=interval_width)]


SCORE_HEAD = ["median error", "p90", "68 % coverage", "95 % coverage", "median 95 % width"]


# ------------------------------------------------------------------------------------------------ tables
def forward_models_within() -> str:
    d = _load("forward_models_within.json")
    b = d["bayes"]
    rows = [[label, str(d["fit"][key]["n"]), *_score_cells(d["fit"][key])]
            for label, key in (("`fit`, 10-40 Hz sweep at 3°", "3"), ("`fit`, 3° + 12° sweeps", "3+12"),
                               ("`fit`, 12° sweep alone", "12"))]
    rows.append([f"`identify --agent bayes` ({b['probes']:.1f} probes, {b['sim_s']:.0f} simulated s)", str(b["n"]),
                 *_score_cells(b)])
    return _table(["identification", "objects", *SCORE_HEAD], rows)


def forward_models_within_sampling() -> str:
    d = _load("forward_models_within.json")
    rows = []
    for part, what in (("fit_more", "120 more test objects (seed 210)"), ("fit_pooled", "both test sets pooled"),
                       ("fit_calibration_in_sample", "calibration set (in sample)")):
        for key, s in d[part].items():
            rows.append([f"{key.replace('+', '° + ')}°, {what}", str(s["n"]), *_score_cells(s)])
    return _table(["sweeps", "objects", *SCORE_HEAD], rows)


def forward_models_nuisance() -> str:
    d = _load("forward_models_nuisance.json")
    rows = [[f"{label}, discrepancy {_dist(s['sigma_eps'], s['eps_nu'])}", *_score_cells(s),
             _stat(s["no_estimate"], 1, 2, interval=False)] for label, s in d.items()]
    return _table(["forward model", *SCORE_HEAD, "no estimate"], rows)


FAMILY = {"pointmass": "point mass", "rigid": "rigid_limit", "pybullet": "PyBullet"}


def forward_models_lomo() -> str:
    d = _load("forward_models_lomo.json")
    rows = []
    for fam, s in d["lomo"].items():
        rows.append([f"{FAMILY[fam]} ({s['n']})",
                     f"{_dist(s['offset_sigma'], s['offset_nu'])} + {_dist(s['sigma_eps'], s['eps_nu'])}",
                     *_score_cells(s), _stat(s["no_estimate"], 1, 2, interval=False)])
    for fam, s in d["lomo"].items():
        o = s["object_level"]
        rows.append([f"*object-level fit:* {FAMILY[fam]}", _dist(o["sigma_eps"], o["eps_nu"]), *_score_cells(o),
                     _stat(o["no_estimate"], 1, 2, interval=False)])
    return _table(["data left out", "discrepancy (offset + scatter)", *SCORE_HEAD, "no estimate"], rows)


def forward_models_cross() -> str:
    """Each model's data through each other model, no discrepancy term: median error, mean bias of
    log(truth / estimate), 95 % coverage (the ``cross`` cells of forward_models_lomo.json)."""
    d = _load("forward_models_lomo.json")["cross"]
    fams = list(dict.fromkeys(k.split("->")[0] for k in d))
    head = {"pointmass": "point mass (9 members)", "rigid": "rigid tiles (`rigid_limit` atlas)",
            "pybullet": "PyBullet sheet"}
    rows = []
    for src in fams:
        cells = []
        for fam in fams:
            c = d[f"{src}->{fam}"]
            cells.append(f"{100 * c['median_error']:.0f} %, {100 * c['bias']:+.0f} %, {c['coverage95']:.2f}")
        rows.append([FAMILY[src], *cells])
    return _table(["data \\ model", *(head.get(f, FAMILY[f]) for f in fams)], rows)


def forward_models_lab() -> str:
    lab = _load("forward_models_lomo.json")["lab"]
    return _table(["shipped `lab` forward model", "offset between models", "scatter of objects"],
                  [[" + ".join(FAMILY[m] for m in lab["models"]), _dist(lab["offset_sigma"], lab["offset_nu"]),
                    _dist(lab["sigma_eps"], lab["eps_nu"])]])


def forward_models_paper() -> str:
    d = _load("forward_models_paper.json")
    rows = []
    for r in d["rows"]:
        ests = ", ".join(f"{e['omega_n_pi']:.2f} [{e['omega_n_ci95_rad_s'][0] / math.pi:.2f}, "
                         f"{e['omega_n_ci95_rad_s'][1] / math.pi:.2f}]" if e["ok"] else f"no estimate ({e['reason']})"
                         for e in r["estimates"])
        amps = r["amplitudes"].replace("+", "° + ")
        rows.append([f"{r['object']} ({r['mass_g']:g} g, {r['omega_n_pi']:.2f}π)", f"{amps}°", f"`{r['forward']}`",
                     ests])
    return _table(["object (mass, true ω_n)", "sweeps", "forward model", "ω̂_n [95 %] of 3 placements, π rad/s"],
                  rows)


def forward_models_lorentz() -> str:
    d = _load("forward_models_lorentz.json")
    rows = []
    for label, c in d["lines"].items():
        name = " + ".join(FAMILY[f] for f in label.split(" + "))
        name = f"all ({name}, shipped as `lab`)" if " + " in label else name
        rows.append([name, str(c["n"]), f"{c['p1'] / math.pi:.2f} ± {c['p1_se'] / math.pi:.2f}",
                     f"{c['q1'] / math.pi:.1f} ± {c['q1_se'] / math.pi:.1f}", f"{c['r2']:.2f}",
                     f"{c['resid_std'] / math.pi:.1f}"])
    return _table(["Eq. (10) line from", "sweeps that fit", "p1 (π rad/s per Hz)", "q1 (π rad/s)", "R²",
                   "residual sd (π rad/s)"], rows)


def forward_models_lorentz_lomo() -> str:
    d = _load("forward_models_lorentz.json")
    rows = [[f"{FAMILY[fam]} ({s['n']})", *_score_cells(s), _stat(s["no_estimate"], 1, 2, interval=False)]
            for fam, s in d["lomo"].items()]
    return _table(["data left out (line from the other two)", *SCORE_HEAD, "no estimate"], rows)


def forward_models_choice() -> str:
    """The README's guide to ``--forward``: what each shipped forward model's intervals held in its study."""
    within = _load("forward_models_within.json")["fit"]["3"]
    nuis = _load("forward_models_nuisance.json")["nuisance family (9 members, evidence)"]
    lomo = _load("forward_models_lomo.json")["lomo"]
    cov = ", ".join(f"{FAMILY[f]} {_stat(s['coverage95'], 1, 2, interval=False)}" for f, s in lomo.items())
    err = ", ".join(f"{FAMILY[f]} {_stat(s['median_error'], 100, 0, ' %', interval=False)}" for f, s in lomo.items())
    wid = ", ".join(f"{FAMILY[f]} {_stat(s['width95'], 100, 0, ' %', interval=False)}" for f, s in lomo.items())
    rows = [["`tilelink/pointmass`", "data from the point-mass simulator, every value known (study `within`)",
             _stat(within["median_error"], 100, 1, " %", interval=False),
             _stat(within["coverage95"], 1, 2, interval=False), _stat(within["width95"], 100, 0, " %", False)],
            ["`lab`'s 9 point-mass members alone", "point-mass data, joint and contact values unknown (`nuisance`)",
             _stat(nuis["median_error"], 100, 1, " %", interval=False),
             _stat(nuis["coverage95"], 1, 2, interval=False), _stat(nuis["width95"], 100, 0, " %", False)],
            ["`lab` (default)", "data of unknown origin, a real plate: each simulator left out in turn (`lomo`)",
             err, cov, wid]]
    return _table(["`--forward`", "for", "median error", "95 % coverage", "median 95 % width"], rows)


def _leaderboard(suite: str, full: bool) -> str:
    d = _load(f"leaderboard_{suite}.json")
    rows = []
    for rank, a in enumerate(d["agents"], 1):
        at = {b["budget_s"]: b for b in a["budgets"]}
        last = at[max(at)]
        cells = [str(rank), f"`{a['label']}`", _stat(a["area"], 100, 1)]
        if full:
            cells += [_stat(at[b]["median_error"], 100, 1) for b in sorted(at)[:-1]]
        cells += [_stat(last["median_error"], 100, 1), _stat(last["p90_error"], 100, 1),
                  " / ".join(_stat(last[c], 100, 0, interval=full) for c in ("coverage68", "coverage95")),
                  _stat(last["no_estimate"], 100, 0, interval=full), f"{last['probes_mean']:.1f}"]
        if full:
            cells.append(f"{a['seconds_per_decision']['value']:.2g}")
        rows.append(cells)
    budgets = sorted(b["budget_s"] for b in d["agents"][0]["budgets"])
    head = ["rank", "agent", f"area: mean median error over 0-{budgets[-1]:g} s (%)"]
    if full:
        head += [f"median error @ {b:g} s (%)" for b in budgets[:-1]]
    head += [f"median error @ {budgets[-1]:g} s (%)", f"p90 @ {budgets[-1]:g} s (%)", "coverage 68 / 95 (%)",
             "no estimate (%)", "probes"]
    if full:
        head.append("wall s per decision")
    caption = f"Suite `{suite}` ({d['agents'][0]['n']} objects; sha256 {d['suite_sha256'][:12]}).\n\n" if full else ""
    return caption + _table(head, rows)


def _paired(suite: str) -> str:
    d = _load(f"leaderboard_{suite}.json")
    paired = d["paired_against_leader"]
    budgets = sorted({float(b) for p in paired.values() for b in p})
    rows = [[f"`{agent}`", *(_stat(p[f"{b:g}"], 100, 1) for b in budgets)] for agent, p in paired.items()]
    return _table([f"agent - `{d['leader']}` (points)", *(f"@ {b:g} s" for b in budgets)], rows)


def misspec_matrix() -> str:
    """The misspecification track (issue 33): each agent and the forward model its estimate went through (rows)
    against the physics that answered the probes (columns), at the largest budget: median error [95 % CI], p90,
    95 % coverage, no-estimate share (experiments/results/misspec-v0.json, one `plate-env bench` run)."""
    d = _load("misspec-v0.json")
    physics = {"misspec_pointmass-v0": "point mass", "misspec_faithful-v0": "rigid tiles (faithful)",
               "misspec_pybullet-v0": "PyBullet sheet"}
    suites = [s["suite"] for s in d["suites"]]
    cell = {(s["suite"], a["label"]): a for s in d["suites"] for a in s["agents"]}
    labels = list(dict.fromkeys(a["label"] for s in d["suites"] for a in s["agents"]))
    order = {lab: i for i, lab in enumerate(labels)}
    labels.sort(key=lambda lab: (lab.split(":")[0].split("path=")[0], order[lab]))
    rows = []
    for label in labels:
        cells = [f"`{label}`"]
        for suite in suites:
            a = cell.get((suite, label))
            if a is None:
                cells.append("-")
                continue
            b = max(a["budgets"], key=lambda x: x["budget_s"])
            cells.append(f"{_stat(b['median_error'], 100, 1)} · {_stat(b['p90_error'], 100, 0, interval=False)} · "
                         f"{_stat(b['coverage95'], 100, 0, interval=False)} · "
                         f"{_stat(b['no_estimate'], 100, 0, interval=False)}")
        rows.append(cells)
    return _table(["agent (estimate through)", *(f"{physics.get(s, s)} (`{s}`)" for s in suites)], rows)


#: The routes of experiments/results/rigid_fast.json shown in docs/rigid_fast.md, with the model each one is.
RIGID_ROUTES = {"small_steps": "`rigid_fast` (shipped; measured at 79d4669, load 1.7)",
                "small_steps_690d019": "`rigid_fast` on the kernel of 690d019 (load 14)",
                "rigid_2e-4": "`rigid` (shipped)",
                "small_steps_5e-5": "small steps at twice the step", "exact_joint_solve_1e-4": "joints solved exactly"}


def rigid_fast_routes() -> str:
    """Each rigid-tile route against the converged rigid limit, and its speed as a share of the point mass's in the
    same run (experiments/rigid_fast_validation.py)."""
    d = _load("rigid_fast.json")
    rows = []
    for key, label in RIGID_ROUTES.items():
        r = d["routes"][key]
        c, sp = r["compare"]["summary"], r["speed"]
        share = [sp["route"][k] / sp["pointmass"][k] for k in ("one_probe_rtf", "batch32_rtf")]
        rows.append([label, f"{r['dt']:g}",
                     f"{100 * c['median_abs_rel']:.1f} % / {100 * c['max_abs_rel']:.1f} % ({c['n_both_stable']} "
                     f"of {c['n_probes']} probes)", f"{100 * c['stability_agreement']:.0f} %",
                     f"{c['max_abs_f0_diff_hz']:.2f} ({c['n_fits_compared']} of {c['n_fits_reference']} fits)",
                     f"{share[0]:.3f} / {share[1]:.3f}", f"{sp['load_avg_1min']:.0f}"])
    return (f"Against `rigid_limit` at dt {d['reference_dt']:g} s ({d['n_reference']} probes).\n\n"
            + _table(["model", "dt (s)", "omega_B median / max abs difference (both stable)", "stability calls agree",
                      "max abs f0 difference (Hz)", "speed: share of the point mass's, one probe / batch of 32",
                      "load"], rows))


def validate_paper_counts() -> str:
    """How many of the paper's published numbers each physics model matches (experiments/validate_paper.py)."""
    d = _load("validate_paper.json")
    head = ["model", *d["verdict_counts"][next(iter(d["verdict_counts"]))]]
    rows = [[f"`{m}`", *(str(n) for n in c.values())] for m, c in d["verdict_counts"].items()]
    return _table(head, rows) + f"\n\nCounts over the table's {len(d['table'])} scalar rows."


def bench_models() -> str:
    """The tile-link models' first-hump fits beside the paper's (Fig. 7 objects), their f0 slopes and speeds
    (experiments/bench_models.py)."""
    d = _load("bench_models.json")
    models = list(d["slope_hz_per_pi"])
    fits = {(f["omega_n_pi"], f["alpha_deg"], f["model"]): f for f in d["fits"]}

    def fbw(f0: float, b: float, wmax: float) -> str:
        return f"{f0:.1f} / {b:.1f} / {wmax:.0f}"

    def rtf(x: float) -> str:
        return f"{x:.0f}x" if x >= 10 else f"{x:.1f}x"

    rows = []
    for wn, alpha, _ in (k for k in fits if k[2] == models[0] and fits[k]["paper"]):
        paper = fits[(wn, alpha, models[0])]["paper"]
        rows.append([f"{wn:g}π, {alpha:g}°", fbw(*paper),
                     *(fbw(*(fits[(wn, alpha, m)][k] for k in ("f0_hz", "b_hz", "omega_max_deg_s"))) for m in models)])
    rows.append(["f0 slope (Hz per π rad/s)", f"{d['paper_slope_hz_per_pi']:.3f}",
                 *(f"{d['slope_hz_per_pi'][m]:.3f}" for m in models)])
    rows.append(["one probe / batch of 32, real-time factor", "",
                 *(f"{rtf(d['speed'][m]['one_probe_rtf'])} / {rtf(d['speed'][m]['batch32_rtf'])}" for m in models)])
    return _table(["ω_n, α", "paper f0 / b / ω_max", *(m.replace("pointmass", "point mass") for m in models)], rows)


#: Every generated table: its name in the markers, the result file it is rendered from, and the renderer.
def env_info() -> str:
    """The env's info schema (plate_env.env.info.FIELDS), the one declaration of its keys."""
    from plate_env.env import info

    return info.markdown()


TABLES: dict[str, tuple[str, Callable[[], str]]] = {
    "forward_models_within": ("forward_models_within.json", forward_models_within),
    "forward_models_within_sampling": ("forward_models_within.json", forward_models_within_sampling),
    "forward_models_nuisance": ("forward_models_nuisance.json", forward_models_nuisance),
    "forward_models_lomo": ("forward_models_lomo.json", forward_models_lomo),
    "forward_models_lab": ("forward_models_lomo.json", forward_models_lab),
    "forward_models_cross": ("forward_models_lomo.json", forward_models_cross),
    "forward_models_paper": ("forward_models_paper.json", forward_models_paper),
    "forward_models_lorentz": ("forward_models_lorentz.json", forward_models_lorentz),
    "forward_models_lorentz_lomo": ("forward_models_lorentz.json", forward_models_lorentz_lomo),
    "forward_models_choice": ("forward_models_{within,nuisance,lomo}.json", forward_models_choice),
    "leaderboard_tilelink-v0": ("leaderboard_tilelink-v0.json", lambda: _leaderboard("tilelink-v0", False)),
    "leaderboard_tilelink-v0_full": ("leaderboard_tilelink-v0.json", lambda: _leaderboard("tilelink-v0", True)),
    "leaderboard_tilelink-v0_paired": ("leaderboard_tilelink-v0.json", lambda: _paired("tilelink-v0")),
    "leaderboard_atlas-v0": ("leaderboard_atlas-v0.json", lambda: _leaderboard("atlas-v0", False)),
    "leaderboard_faithful-v0": ("leaderboard_faithful-v0.json", lambda: _leaderboard("faithful-v0", False)),
    "leaderboard_faithful-v0_paired": ("leaderboard_faithful-v0.json", lambda: _paired("faithful-v0")),
    "leaderboard_rigid-v0": ("leaderboard_rigid-v0.json", lambda: _leaderboard("rigid-v0", True)),
    "leaderboard_rigid-v0_paired": ("leaderboard_rigid-v0.json", lambda: _paired("rigid-v0")),
    "misspec_matrix": ("misspec-v0.json", misspec_matrix),
    "rigid_fast_routes": ("rigid_fast.json", rigid_fast_routes),
    "validate_paper_counts": ("validate_paper.json", validate_paper_counts),
    "bench_models": ("bench_models.json", bench_models),
    "env_info": ("plate_env/env/info.py", env_info),
}


def render(name: str) -> str:
    """The table ``name`` from its result file, with a line naming that file."""
    if name not in TABLES:
        raise KeyError(f"unknown table {name!r}; known: {', '.join(TABLES)}")
    source, fn = TABLES[name]
    where = source if source.startswith("plate_env/") else f"experiments/results/{source}"
    return (f"{fn()}\n\n<sub>Rendered from `{where}` by `python experiments/readme_tables.py`; "
            "do not edit by hand.</sub>\n")


def pages(root: Path = ROOT) -> list[Path]:
    """README.md and every markdown page under docs/."""
    out = []
    for p in PAGES:
        path = root / p
        out += sorted(path.rglob("*.md")) if path.is_dir() else [path] if path.exists() else []
    return out


def splice(text: str) -> str:
    """``text`` with every marked table re-rendered."""
    return MARKER.sub(lambda m: f"<!-- table: {m['name']} -->\n{render(m['name'])}<!-- /table -->", text)


def stale(text: str) -> list[str]:
    """Names of the marked tables of ``text`` that differ from their result files."""
    return [m["name"] for m in MARKER.finditer(text) if m["body"] != render(m["name"])]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="only check; exit 1 naming each table that drifted")
    args = ap.parse_args(argv)
    bad = 0
    for path in pages():
        text = path.read_text()
        if args.check:
            for name in stale(text):
                print(f"{path.relative_to(ROOT)}: table {name!r} differs from experiments/results/"
                      f"{TABLES[name][0]}; run python experiments/readme_tables.py", file=sys.stderr)
                bad += 1
        elif splice(text) != text:
            path.write_text(splice(text))
            print(f"rewrote {path.relative_to(ROOT)}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
