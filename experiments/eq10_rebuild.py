"""Rebuild the shipped Eq. (10) lines (plate_env/data/calibration.json) with `plate-env build calibration eq10` and
compare them with the shipped file, field by field; with --against COMMIT, also run that commit's
experiments/calibrate.py on this machine (its source from `git archive`, in a temporary directory), natively and told
to compute as another CPU would, and compare its tile-link sweeps probe by probe with the builder's: is a difference
the code's or the machine's?

    python experiments/eq10_rebuild.py [--against 9bdcb3a]

The builder reads every sweep from experiments/cache (the tile-link calibration sweeps and the lab line's point-mass,
rigid_limit and PyBullet sets are committed there; a missing probe would be simulated into it). Writes
experiments/results/eq10_rebuild.json and the markdown rendered from it, eq10_rebuild.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"
CACHE = ROOT / "experiments" / "cache"
SHIPPED = ROOT / "plate_env" / "data" / "calibration.json"
#: How the atlas study made this machine compute as the one that built the shipped atlas (atlas_rebuild.md).
OTHER_CPU = {"OPENBLAS_CORETYPE": "SkylakeX", "NUMBA_CPU_NAME": "sapphirerapids"}
FIELDS = ("n", "p1", "q1", "p1_se", "q1_se", "cov_pq", "r2", "resid_std", "alpha_coef", "alpha_resid_std",
          "model_lines", "provenance")


def rel(a, b) -> float | None:
    """Largest relative difference of two numbers or nested lists of numbers (None for other values)."""
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        parts = [rel(x, y) for x, y in zip(a, b, strict=True)]
        return None if any(p is None for p in parts) else max(parts, default=0.0)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return abs(a - b) / max(abs(a), abs(b), 1e-300) if a != b else 0.0
    return None


def compare(shipped: dict, built: dict) -> dict:
    """Per line and field: equal, or both values and their largest relative difference."""
    out = {}
    for key in sorted(shipped.keys() | built.keys()):
        s, b = shipped.get(key, {}), built.get(key, {})
        out[key] = {f: {"equal": True} if s.get(f) == b.get(f) else
                    {"equal": False, "shipped": s.get(f), "rebuilt": b.get(f), "rel": rel(s.get(f), b.get(f))}
                    for f in FIELDS if f in s or f in b}
    return out


def probe_records(path: Path) -> list[dict]:
    """The sweep cache's records in file order (the spec order: the run was in-process), without the key and the
    wall time."""
    out = []
    for line in path.read_text().splitlines():
        d = json.loads(line)
        d.pop("key")
        d.pop("wall_s", None)
        out.append(d)
    return out


def probe_diff(a: list[dict], b: list[dict]) -> dict:
    stable = [(x["omega_b_deg_s"], y["omega_b_deg_s"]) for x, y in zip(a, b, strict=True)
              if not x["unstable"] and not y["unstable"]]
    rels = [abs(x - y) / max(abs(x), abs(y), 1e-300) for x, y in stable]
    return {"n": len(a), "equal": sum(x == y for x, y in zip(a, b, strict=True)),
            "stability_differs": sum(x["unstable"] != y["unstable"] for x, y in zip(a, b, strict=True)),
            "median_rel": statistics.median(rels), "max_rel": max(rels)}


def against(commit: str, env: dict, builder_probes: list[dict]) -> dict:
    """Run ``commit``'s experiments/calibrate.py here (with ``env`` added) and compare its lines and probes."""
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "src"
        src.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
        run_env = {**os.environ, **env, "PYTHONPATH": str(src), "NUMBA_CACHE_DIR": str(Path(tmp) / "numba")}
        subprocess.run([sys.executable, "experiments/calibrate.py"], cwd=src, env=run_env, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        lines = json.loads((src / "plate_env" / "data" / "calibration.json").read_text())
        probes = probe_records(src / "experiments" / "cache" / "sweeps_tilelink_pointmass.jsonl")
    tile = {k: v for k, v in lines.items() if k.startswith("tilelink/")}
    return {"commit": commit, "env": env, "lines": tile, "probes_vs_builder": probe_diff(probes, builder_probes)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--against", default=None, help="a commit whose experiments/calibrate.py to run here as well")
    args = ap.parse_args()
    from plate_env.build.provenance import git_commit, machine
    from plate_env.cli import main as cli_main

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "calibration.json"
        cache = os.path.relpath(CACHE)
        argv = ["build", "calibration", "eq10", "--sweeps", cache, "--lab-sweeps", cache, "--out", str(out)]
        if cli_main(argv) != 0:
            sys.exit("the builder failed")
        built_bytes = out.read_bytes()
    built, shipped = json.loads(built_bytes), json.loads(SHIPPED.read_text())
    numbers = {"command": "python experiments/eq10_rebuild.py" + (f" --against {args.against}" if args.against
                                                                   else ""),
               "builder": "plate-env " + " ".join(argv[:-1]) + " FILE", "commit": git_commit(ROOT),
               "machine": machine(), "same_bytes": built_bytes == SHIPPED.read_bytes(), "rebuilt": built,
               "fields": compare(shipped, built), "against": []}
    if args.against:
        mine = probe_records(CACHE / "sweeps_tilelink_pointmass.jsonl")
        for env in ({}, OTHER_CPU):
            numbers["against"].append(against(args.against, env, mine))
    (RESULTS / "eq10_rebuild.json").write_text(json.dumps(numbers, indent=1) + "\n")
    text = render(numbers, shipped)
    (RESULTS / "eq10_rebuild.md").write_text(text)
    print(text)


def _g(x) -> str:
    return "-" if x is None else f"{x:.3g}"


def render(d: dict, shipped: dict) -> str:
    """The markdown of the study's JSON."""
    lines = ["# The Eq. (10) lines rebuilt (`plate-env build calibration eq10`)", "",
             f"`{d['command']}` at commit {d['commit']} (machine: {d['machine']['numba_cpu']}, "
             f"{', '.join(d['machine']['blas'])}). Builder: `{d['builder']}`. The rebuilt file "
             f"{'equals' if d['same_bytes'] else 'differs from'} the shipped one byte for byte.", "",
             "| line | sweeps fitted (shipped -> rebuilt) | p1 [pi rad/s per Hz] | q1 [pi rad/s] | fields that differ "
             "(largest relative difference) |", "|---|---|---|---|---|"]
    for key, fields in d["fields"].items():
        s, b = shipped.get(key, {}), d["rebuilt"].get(key, {})
        diff = ", ".join(f"{f} ({_g(v['rel'])})" if v["rel"] is not None else f
                         for f, v in fields.items() if not v["equal"]) or "none"
        lines.append(f"| {key} | {s.get('n')} -> {b.get('n')} | {s['p1'] / math.pi:.6f} -> {b['p1'] / math.pi:.6f} | "
                     f"{s['q1'] / math.pi:.4f} -> {b['q1'] / math.pi:.4f} | {diff} |")
    lab_s, lab_b = shipped["lab/lab/3"], d["rebuilt"]["lab/lab/3"]
    fams = sorted(lab_b["provenance"]["sweeps"])  # model_lines are in sorted family order (fit_calibration)
    lines += ["", "The lab line's own line per family (p1, q1 in pi rad/s per Hz, pi rad/s), shipped -> rebuilt:", "",
              "| family | shipped | rebuilt | largest relative difference |", "|---|---|---|---|"]
    for fam, a, b in zip(fams, lab_s["model_lines"], lab_b["model_lines"], strict=True):
        lines.append(f"| {fam} | {a[0] / math.pi:.6f}, {a[1] / math.pi:.4f} | {b[0] / math.pi:.6f}, "
                     f"{b[1] / math.pi:.4f} | {_g(rel(a, b))} |")
    if d["against"]:
        lines += ["", "## The shipped lines' own code, run here", "",
                  "The tile-link lines were shipped by experiments/calibrate.py at the commit below; its sweeps, run "
                  "on this machine natively and with the CPU settings of the atlas study, against the builder's:", "",
                  "| run | tilelink/pointmass/3 p1 | /12 p1 | sweeps fitted at 12 deg | probes equal to the builder's "
                  "| stability differs | median / max relative difference of omega_B |",
                  "|---|---|---|---|---|---|---|"]
        rows = [("shipped file", shipped, None), ("builder", d["rebuilt"], None)]
        rows += [(f"{a['commit']} " + (" ".join(f"{k}={v}" for k, v in a["env"].items()) or "native"), a["lines"],
                  a["probes_vs_builder"]) for a in d["against"]]
        for label, ls, p in rows:
            probe = (f"{p['equal']} of {p['n']} | {p['stability_differs']} | {_g(p['median_rel'])} / "
                     f"{_g(p['max_rel'])}") if p else "- | - | -"
            lines.append(f"| {label} | {ls['tilelink/pointmass/3']['p1'] / math.pi:.7f} | "
                         f"{ls['tilelink/pointmass/12']['p1'] / math.pi:.5f} | {ls['tilelink/pointmass/12']['n']} | "
                         f"{probe} |")
        def off(ls: dict) -> str:  # the largest relative difference of a run's tile-link p1, q1 from the builder's
            return _g(max(rel([ls[k]["p1"], ls[k]["q1"]], [d["rebuilt"][k]["p1"], d["rebuilt"][k]["q1"]])
                          for k in ("tilelink/pointmass/3", "tilelink/pointmass/12")))
        runs = [(f"{a['commit']} {'told to compute as another CPU' if a['env'] else 'natively'}", a["lines"])
                for a in d["against"]] + [("the shipped file", shipped)]
        lines += ["", "Reading (sweeps that fit at 12 deg, largest relative difference of the tile-link lines' p1 and "
                  "q1 from the builder's): " + "; ".join(f"{label} {ls['tilelink/pointmass/12']['n']}, {off(ls)}"
                                                        for label, ls in runs)
                  + ". So a rebuild's difference from the shipped lines is the machine the "
                  "file was made on (CPU, and library versions), not the code: probes that sit at the edge of "
                  "stability or of the first hump amplify last-bit differences, and the 12 deg line, fitted on the "
                  "sweeps that have a hump (R^2 ~0.08), moves with each one gained or lost."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
