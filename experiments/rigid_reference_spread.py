"""Issue 34: how far the converged rigid limit's own calls move, before any model is scored against them.

Reads the reference (``experiments/results/rigid_reference.json``: ``rigid_limit`` at dt 6.25e-6 s, centred) and
every variant ``experiments/rigid_reference.py`` has collected beside it: the same probes with the initial yaw moved
by a few mrad (``rigid_reference_yaw{Y}mrad.json``) and the same probes at another step (``..._dt{dt}.json``, all 54
or a subset). Each variant is scored against the reference exactly as the models are (``common.compare``: omega_B
where both are stable, stability agreement on the probes both ran, first-hump f0), and the yaw variants also
against each other (the spread of the calls over placements no lab controls). Another model's runs (``--model``,
e.g. the point mass: the same contact law without the stiff joint rows) are scored against that model at the
reference's placement and step. Nothing is simulated here.

Writes ``experiments/results/rigid_reference_spread.json`` and ``.md``.
Usage: ``python experiments/rigid_reference_spread.py``.
"""

from __future__ import annotations

import itertools
import json
import types
from pathlib import Path

from common import compare, load_reference
from rigid_reference import REFERENCE_DT

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
OUT = RESULTS / "rigid_reference_spread"
REFERENCE = "yaw 0 mrad (the reference)"
#: Models that are forms of the rigid limit (scored against the reference); others against themselves.
RIGID_LIMIT_FORMS = ("rigid_limit", "rigid_fast")


def variants() -> dict[str, dict]:
    """Every collected variant: name -> {yaw_mrad, dt_s, model, rows} (the reference itself as ``yaw 0``). Model,
    step and yaw offset are read from the rows (as ``rigid_reference.record`` wrote them), not from file names."""
    ref = load_reference()
    ref_yaw = {r["key"]: r["initial_yaw_rad"] for r in ref}
    out = {REFERENCE: {"yaw_mrad": 0.0, "dt_s": ref[0]["dt_s"], "model": ref[0]["model"], "rows": ref}}
    for path in sorted(RESULTS.glob("rigid_reference_*.json")):
        if path.name.startswith("rigid_reference_spread"):
            continue
        rows = json.loads(path.read_text())["probes"]
        model, dt = rows[0]["model"], rows[0]["dt_s"]
        yaw = round(1e3 * (rows[0]["initial_yaw_rad"] - ref_yaw[rows[0]["key"]]), 6)
        name = " ".join(([model] if model != "rigid_limit" else []) + ([f"yaw {yaw:g} mrad"] if yaw else [])
                        + ([f"dt {dt:g} s"] if dt != REFERENCE_DT else [])) or model
        out[name] = {"yaw_mrad": yaw, "dt_s": dt, "model": model, "rows": rows}
    return out


def base_of(name: str, var: dict[str, dict]) -> str | None:
    """What a variant is scored against: the reference for a form of the rigid limit, or for another model (the
    point mass) that model at the reference's placement and step (None if not run)."""
    model = var[name]["model"]
    if model in RIGID_LIMIT_FORMS:
        return REFERENCE
    return next((n for n, v in var.items() if v["model"] == model and v["dt_s"] == REFERENCE_DT and not v["yaw_mrad"]
                 and n != name), None)


def _as_results(rows: list[dict]) -> list:
    return [types.SimpleNamespace(omega_b_deg_s=r["omega_b_deg_s"], unstable=r["unstable"], reason=r["reason"])
            for r in rows]


def score(base: list[dict], other: list[dict]) -> dict:
    """``common.compare`` of ``other`` against ``base`` on the probes both ran (by key)."""
    keys = {r["key"] for r in other}
    base = [r for r in base if r["key"] in keys]
    by_key = {r["key"]: r for r in other}
    c = compare(base, _as_results([by_key[r["key"]] for r in base]))
    s = c["summary"]
    differ = [f"{p['key']} ({'unstable' if p['ref_unstable'] else 'stable'} -> "
              f"{'unstable' if p['new_unstable'] else 'stable'})"
              for p in c["probes"] if p["ref_unstable"] != p["new_unstable"]]
    return {"n_probes": s["n_probes"], "n_both_stable": s["n_both_stable"], "median_abs_rel": s["median_abs_rel"],
            "max_abs_rel": s["max_abs_rel"], "stability_agreement": s["stability_agreement"],
            "f0_diff_hz": s["f0_diff_hz"], "calls_that_differ": differ}


def report() -> dict:
    var = variants()
    ref = var[REFERENCE]["rows"]
    order = sorted((n for n in var if n != REFERENCE and base_of(n, var) is not None),
                   key=lambda n: (var[n]["model"] != "rigid_limit", var[n]["model"], var[n]["dt_s"] != REFERENCE_DT,
                                  var[n]["dt_s"], var[n]["yaw_mrad"]))
    against_ref = {f"{name}, against {base_of(name, var)}": score(var[base_of(name, var)]["rows"], var[name]["rows"])
                   for name in order}
    yaws = {name: v for name, v in var.items()
            if v["dt_s"] == REFERENCE_DT and v["model"] == "rigid_limit" and len(v["rows"]) == len(ref)}
    pairs = {f"{a} vs {b}": score(yaws[a]["rows"], yaws[b]["rows"]) for a, b in itertools.combinations(yaws, 2)}
    unstable = {r["key"]: [] for r in ref}
    for v in yaws.values():
        for r in v["rows"]:
            unstable[r["key"]].append(bool(r["unstable"]))
    mixed = sorted(k for k, calls in unstable.items() if 0 < sum(calls) < len(calls))
    return {"description": __doc__.split("\n")[0], "n_reference": len(ref), "against_reference": against_ref,
            "yaw_pairs": pairs, "n_yaw_variants": len(yaws), "probes_whose_call_moves_with_yaw": mixed}


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def markdown(rep: dict) -> str:
    lines = [f"# {rep['description']}", "",
             "Written by `python experiments/rigid_reference_spread.py` from the runs of "
             "`experiments/rigid_reference.py` (`--yaw-offset-mrad Y`, `--dt DT [--keys ...]`). Scores as the models' "
             "(`common.compare`), on the probes each variant ran.", "",
             "| variant, against its base | probes | both stable | median / max abs diff | stability agree "
             "| f0 diff (Hz) | calls that differ |", "|---|---|---|---|---|---|---|"]
    for name, s in rep["against_reference"].items():
        f0 = ", ".join(f"{k} {v:+.3f}" for k, v in s["f0_diff_hz"].items()) or "-"
        lines.append(f"| {name} | {s['n_probes']} | {s['n_both_stable']} | {_pct(s['median_abs_rel'])} / "
                     f"{_pct(s['max_abs_rel'])} | {_pct(s['stability_agreement'])} | {f0} | "
                     f"{'; '.join(s['calls_that_differ']) or 'none'} |")
    ag = [s["stability_agreement"] for s in rep["yaw_pairs"].values()]
    mx = [s["max_abs_rel"] for s in rep["yaw_pairs"].values()]
    if ag:
        lines += ["", f"Between the {rep['n_yaw_variants']} initial yaws (every pair, {len(ag)} pairs, at the "
                  f"reference's step): stability agreement {_pct(min(ag))}-{_pct(max(ag))}, max omega_B difference "
                  f"where both are stable {_pct(min(mx))}-{_pct(max(mx))}. Probes whose call moves with the yaw: "
                  f"{', '.join(rep['probes_whose_call_moves_with_yaw']) or 'none'}."]
    return "\n".join(lines) + "\n"


def main() -> None:
    rep = report()
    OUT.with_suffix(".json").write_text(json.dumps(rep, indent=1) + "\n")
    OUT.with_suffix(".md").write_text(markdown(rep))
    print(markdown(rep))


if __name__ == "__main__":
    main()
