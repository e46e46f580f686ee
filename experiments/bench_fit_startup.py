"""Where a user waits before the first number (issue 25): ``plate-env fit``, the command line's start-up and
PyBullet's first probe, for this tree and an earlier commit, in one run.

    python experiments/bench_fit_startup.py --ref 690d019 [--repeats 5] [--no-pybullet]

Every figure is the wall time of a fresh process (``sys.executable``) whose ``plate_env`` is the tree's (this
checkout, or ``git archive <ref>``: :func:`common.tree_path`), the two trees measured alternately, each
repeat of each figure one after the other, so both see the same load; the median of the repeats and the ratio
before / after are the figures to read (the machine is shared: the load average is recorded before and after).
Each tree has its own disk cache (``PLATE_ENV_CACHE_DIR``), filled by one untimed run of each command first: the
figures are a warm machine's (the ring-down calibration, atlas splines and responses already cached).

- ``fit --forward F``: ``python -m plate_env fit SWEEP --forward F --json`` (common.SWEEP_CSV: 9 points at 3 deg).
- ``import plate_env`` / ``import plate_env.cli``: ``python -c "import ..."`` (the interpreter's own start-up
  included: ``python -c pass`` is reported as the floor).
- ``pybullet``: bench_speed's ``m_pybullet`` (a PyBullet env's reset and first probe after import, the import and
  the scene build apart).

Writes experiments/results/bench_fit_startup.json (the source) and bench_fit_startup.md (generated from it).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import common

HERE = Path(__file__).resolve().parent

RESULTS = HERE / "results"
FORWARDS = ("lab", "tilelink/pointmass")


def timed(cmd: list[str], env: dict) -> tuple[float, float, subprocess.CompletedProcess]:
    """Wall seconds, CPU seconds (user + system of the child: what an idle machine's wall time would be for a
    single-threaded command) and the finished process."""
    r0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(), timeout=3600)
    wall, r1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime), done


def figures(csv: Path, pybullet: bool) -> list[tuple[str, list[str], str | None]]:
    """(label, command, what its stdout's last line holds: None for nothing, else a JSON key to record)."""
    py = sys.executable
    out = [("python -c pass (the interpreter alone)", [py, "-c", "pass"], None),
           ("import plate_env", [py, "-c", "import plate_env"], None),
           ("import plate_env.cli", [py, "-c", "import plate_env.cli"], None)]
    out += [(f"plate-env fit --forward {fm} (whole command)",
             [py, "-m", "plate_env", "fit", str(csv), "--forward", fm, "--json"], "omega_n_rad_s") for fm in FORWARDS]
    if pybullet:
        out.append(("PyBullet first probe", [py, str(common.HERE / "bench_speed.py"), "--measure", "pybullet"],
                    "first_probe_after_import_s"))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", default="690d019", help="git revision measured as 'before'")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs of each command per tree (PyBullet: 2)")
    ap.add_argument("--no-pybullet", action="store_true")
    ap.add_argument("--out", default=str(RESULTS / "bench_fit_startup"), help="results path without extension")
    args = ap.parse_args()
    commit = subprocess.run(["git", "-C", str(common.ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(common.ROOT), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    doc = {"command": "python experiments/bench_fit_startup.py " + " ".join(sys.argv[1:]),
           "commit": commit + ("+dirty" if dirty else ""), "ref": args.ref,
           "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "load_before": list(os.getloadavg()),
           "figures": {}}
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        csv = tmp / "sweep.csv"
        csv.write_text(common.SWEEP_CSV)
        envs = {}
        for label, ref in (("before", args.ref), ("after", None)):
            path = common.overlay(common.tree_path(ref if ref or dirty else "HEAD", tmp), tmp)
            envs[label] = dict(os.environ, PYTHONPATH=str(path), PLATE_ENV_CACHE_DIR=str(tmp / f"cache-{label}"))
        for name, cmd, key in figures(csv, not args.no_pybullet):
            rec = {label: {"wall_s": [], "cpu_s": [], "value": []} for label in envs}
            for label, env in envs.items():  # untimed: fills the tree's disk cache
                wall, _, done = timed(cmd, env)
                rec[label]["first_use_s"] = wall
            for _ in range(2 if key == "first_probe_after_import_s" else args.repeats):
                for label, env in envs.items():
                    wall, cpu, done = timed(cmd, env)
                    if done.returncode not in (0, 1) or (key and not done.stdout.strip()):
                        raise SystemExit(f"{name} ({label}) failed: {done.stderr.strip()[-500:]}")
                    rec[label]["wall_s"].append(wall)
                    rec[label]["cpu_s"].append(cpu)
                    if key:
                        value = json.loads(done.stdout.strip().splitlines()[-1])[key]
                        rec[label]["value"].append(value)
                        if key != "omega_n_rad_s":
                            rec[label].setdefault("detail", []).append(json.loads(done.stdout.strip().splitlines()[-1]))
            for label in envs:
                vals = rec[label]["value"] if key == "first_probe_after_import_s" else rec[label]["wall_s"]
                rec[label]["median_s"] = statistics.median(vals)
                rec[label]["median_cpu_s"] = statistics.median(rec[label]["cpu_s"])
            if key == "omega_n_rad_s":  # the fit's number is the same before and after
                rec["same_result"] = len({json.dumps(v) for lab in envs for v in rec[lab]["value"]}) == 1
            doc["figures"][name] = rec
            print(f"{name}: before {rec['before']['median_s']:.3f} s, after {rec['after']['median_s']:.3f} s",
                  file=sys.stderr, flush=True)
    doc["load_after"] = list(os.getloadavg())
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1) + "\n")
    out.with_suffix(".md").write_text(markdown(doc))
    print(markdown(doc))


GOALS = {"plate-env fit --forward lab (whole command)": "<= 1",
         "plate-env fit --forward tilelink/pointmass (whole command)": "<= 1", "PyBullet first probe": "<= 3"}


def markdown(doc: dict) -> str:
    lines = ["# `plate-env fit`, start-up and PyBullet's first probe (issue 25)", "",
             f"Generated from bench_fit_startup.json by `{doc['command']}` ({doc['date_utc']}). Load average (1 min) "
             f"{doc['load_before'][0]:.1f} before, {doc['load_after'][0]:.1f} after, on the shared 2-core machine: "
             "read the ratios (same run, same load, the trees alternating), not the seconds. Warm disk cache; "
             "medians of fresh processes. CPU s: user + system time of the whole process (what an idle machine's "
             "wall time would be: the commands are single-threaded).", "",
             f"| figure (wall s) | goal | before ({doc['ref']}) | after ({doc['commit']}) | before / after (x faster) "
             "| CPU s before | CPU s after | same result |", "|---|---|---|---|---|---|---|---|"]
    for name, rec in doc["figures"].items():
        b, a = rec["before"]["median_s"], rec["after"]["median_s"]
        same = {True: "yes", False: "**no**"}.get(rec.get("same_result"), "")
        cb, ca = rec["before"].get("median_cpu_s"), rec["after"].get("median_cpu_s")
        cpu = f"{cb:.3g} | {ca:.3g}" if cb is not None and ca is not None else " | "
        lines.append(f"| {name} | {GOALS.get(name, '')} | {b:.3g} | {a:.3g} | {b / a:.3g} | {cpu} | {same} |")
    pb = doc["figures"].get("PyBullet first probe")
    if pb:
        lines += ["", "PyBullet's first probe, split (medians; the probe simulates `sim_s` s at the backend's "
                  "dt = 4e-4 s):", "",
                  "| tree | import s | scene build s | ring-down calibration s | probe s | sim_s |",
                  "|---|---|---|---|---|---|"]
        for label in ("before", "after"):
            d = pb[label].get("detail", [])
            med = {k: statistics.median(x[k] for x in d) for k in ("import_s", "scene_build_s", "calibration_s",
                                                                  "first_probe_s", "sim_s")} if d else {}
            if med:
                lines.append(f"| {label} | {med['import_s']:.3g} | {med['scene_build_s']:.3g} | "
                             f"{med['calibration_s']:.3g} | {med['first_probe_s']:.3g} | {med['sim_s']:.3g} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
