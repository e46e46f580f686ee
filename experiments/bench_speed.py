"""Speed where users wait (issue 25): every figure in one run, for this tree and, with ``--ref``, an earlier commit.

    python experiments/bench_speed.py --ref 284a76f [--quick] [--no-pybullet]

Each measurement runs in a fresh Python process whose ``plate_env`` and ``plate_env_agents`` are those of the tree
under test (this checkout, or ``git archive <ref>`` unpacked into a temporary directory), so the two columns come
from the same machine at the same time and their ratio is the figure to read (the machine is shared: the load
average, ``os.getloadavg``, is recorded before and after). Measured, with the public API both trees share:

- ``env``: the atlas env (``gym.make("PlateRotation-v0", physics="atlas")``) stepped with random probe actions
  that stop an episode with probability 0.1 per step (episodes of ~10 probes, every end and reset counted):
  env steps per wall second, median of repeats.
- ``vec``: aggregate steps per second through ``plate_env.sb3.make_sb3_vec_env(16, physics="atlas")`` (one
  batched physics call per step; SB3's auto-reset), in one process and in two processes at once (the 2 cores).
- ``start``: from a cold process, ``gym.make`` + ``reset`` + the first step, and the first episode end.
- ``fit``: ``plate-env fit`` of a 9-point sweep at 3 deg (10-26 Hz) on every shipped forward model: wall seconds of the
  whole command (cold process) and of ``identify`` alone after the imports.
- ``bayes``: seconds per decision of the bayes agent (``next_probe``) on atlas episodes of tilelink/pointmass, and
  the episode's estimate.
- ``pybullet``: a PyBullet env's first probe from a cold process, split into the scene build, the object's
  omega_n calibration (ring-downs) and the rest.

Writes experiments/results/bench_speed.json (the source) and bench_speed.md (generated from it).
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
import time
from pathlib import Path

from common import SWEEP_CSV, SWEEP_POINTS, attr, overlay, tree_path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results"


# ------------------------------------------------------------------------------------------- measurements


# Each runs in a fresh process (``--measure NAME``) and prints one JSON line.
def random_action(rng, stop_p: float = 0.1):
    import numpy as np

    a = rng.uniform(-1, 1, 4).astype(np.float32)
    a[3] = 1.0 if rng.uniform() < stop_p else -1.0
    return a


def m_env(quick: bool) -> dict:
    import gymnasium as gym
    import numpy as np

    import plate_env  # noqa: F401

    env = gym.make("PlateRotation-v0", physics="atlas")
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    for _ in range(50):  # warm up: load the forward model and atlas once
        *_, term, trunc, _ = env.step(random_action(rng))
        if term or trunc:
            env.reset()
    rates, cpu_rates, ends = [], [], 0
    n = 300 if quick else 1000
    for rep in range(3):
        env.reset(seed=rep + 1)
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(n):
            *_, term, trunc, _ = env.step(random_action(rng))
            if term or trunc:
                ends += 1
                env.reset()
        rates.append(n / (time.perf_counter() - t0))
        cpu_rates.append(n / max(time.process_time() - c0, 1e-9))
    return {"steps_per_s": statistics.median(rates), "rates": rates, "episode_ends": ends,
            "steps_per_cpu_s": statistics.median(cpu_rates)}


def m_vec(quick: bool) -> dict:
    import numpy as np

    make_sb3_vec_env = attr("plate_env.env.sb3", "plate_env.sb3", "make_sb3_vec_env")

    n_envs = 16
    venv = make_sb3_vec_env(n_envs, seed=0, physics="atlas")
    venv.reset()
    rng = np.random.default_rng(0)

    def acts():
        return np.stack([random_action(rng) for _ in range(n_envs)])

    for _ in range(20):
        venv.step(acts())
    rates, cpu_rates, ends = [], [], 0
    n = 40 if quick else 100
    for _ in range(3):
        batch = [acts() for _ in range(n)]
        t0, c0 = time.perf_counter(), time.process_time()
        for a in batch:
            _, _, dones, _ = venv.step(a)
            ends += int(dones.sum())
        rates.append(n * n_envs / (time.perf_counter() - t0))
        cpu_rates.append(n * n_envs / max(time.process_time() - c0, 1e-9))
    venv.close()
    return {"steps_per_s": statistics.median(rates), "rates": rates, "episode_ends": ends, "n_envs": n_envs,
            "steps_per_cpu_s": statistics.median(cpu_rates)}


def m_start(quick: bool) -> dict:
    t0 = time.perf_counter()
    import gymnasium as gym
    import numpy as np

    import plate_env  # noqa: F401
    t1 = time.perf_counter()
    env = gym.make("PlateRotation-v0", physics="atlas")
    env.reset(seed=0)
    t2 = time.perf_counter()
    u = env.unwrapped
    env.step(u.encode_action(20.0, 3.0, 1.0))
    t3 = time.perf_counter()
    for f in (24.0, 28.0):
        env.step(u.encode_action(f, 3.0, 1.0))
    t4 = time.perf_counter()
    _, _, term, _, info = env.step(u.encode_action(stop=True))
    t5 = time.perf_counter()
    assert term and "estimate" in info
    del np
    return {"import_s": t1 - t0, "make_reset_s": t2 - t1, "first_step_s": t3 - t2,
            "make_to_first_step_s": t3 - t1, "first_episode_end_s": t5 - t4}


def m_fit_inproc(quick: bool, forward: str, csv: str) -> dict:
    t0 = time.perf_counter()
    from plate_env.identify import identify

    known_inputs = attr("plate_env.surrogate.conditioning", "plate_env.forward", "KnownInputs")
    read_lab_csv = attr("plate_env.core.probe_table", "plate_env.probes", "read_lab_csv")

    t1 = time.perf_counter()
    table = read_lab_csv(csv)
    est = identify(table, method="atlas", forward=forward, known=known_inputs())
    t2 = time.perf_counter()
    est2 = identify(table, method="atlas", forward=forward, known=known_inputs())
    t3 = time.perf_counter()
    return {"import_s": t1 - t0, "identify_s": t2 - t1, "second_identify_s": t3 - t2, "ok": est.ok,
            "omega_n": est.omega_n, "same_twice": est.omega_n == est2.omega_n}


def m_bayes(quick: bool) -> dict:
    from plate_env.env import PlateRotationEnv
    from plate_env_agents import make_agent

    run_episode = attr("plate_env.env.episode", "plate_env.episode", "run_episode")

    env = PlateRotationEnv(physics="atlas")
    agent = make_agent("bayes")
    run_episode(env, agent, seed=99)  # warm up (forward model, responses)
    cpu: list[float] = []
    next_probe = agent.next_probe

    def timed(*a, **k):  # the decision's CPU seconds too (the machine is shared: wall time includes waiting)
        c0 = time.process_time()
        try:
            return next_probe(*a, **k)
        finally:
            cpu.append(time.process_time() - c0)

    agent.next_probe = timed
    decisions, ends, errs, probes, picked = [], [], [], [], []
    for seed in range(3 if quick else 5):
        t0 = time.perf_counter()
        res = run_episode(env, agent, seed=seed)
        wall = time.perf_counter() - t0
        decisions += list(res.decision_wall_s)
        ends.append(wall - sum(res.decision_wall_s))
        errs.append(res.relative_error if res.estimate.ok else None)
        probes.append(res.n_probes)
        picked.append([[float(f), float(a)] for f, a in zip(res.probes.f_p_hz, res.probes.a_p_deg, strict=True)])
    return {"s_per_decision": statistics.median(decisions), "decisions": len(decisions),
            "cpu_s_per_decision": statistics.median(cpu), "max_s_per_decision": max(decisions),
            "rest_of_episode_s": statistics.median(ends), "relative_errors": errs, "n_probes": probes,
            "probes": picked}


def m_pybullet(quick: bool) -> dict:
    import math

    t0 = time.perf_counter()
    from plate_env.env import PlateRotationEnv
    from plate_env.physics.pybullet_sheet import calibrate, scene
    t_imp = time.perf_counter() - t0
    cal = {"s": 0.0, "n": 0}
    build = {"s": 0.0}
    ring, init = calibrate.ringdown_omega_n, scene.SheetScene.__init__

    def timed_ring(*a, **k):
        t = time.perf_counter()
        try:
            return ring(*a, **k)
        finally:
            cal["s"] += time.perf_counter() - t
            cal["n"] += 1

    def timed_init(self, *a, **k):
        t = time.perf_counter()
        try:
            return init(self, *a, **k)
        finally:
            build["s"] += time.perf_counter() - t

    calibrate.ringdown_omega_n = timed_ring
    scene.SheetScene.__init__ = timed_init
    t1 = time.perf_counter()
    env = PlateRotationEnv(physics="pybullet", amplitudes_deg=(3.0,), f_band_hz=(10.0, 26.0), settle_s=0.3,
                           measure_range_s=(0.4, 1.0))
    env.reset(seed=0, options={"omega_n": 15 * math.pi, "alpha": 0.7})
    t2 = time.perf_counter()
    _, _, _, _, info = env.step(env.encode_action(18.0, 3.0, 0.6))
    t3 = time.perf_counter()
    env.close()
    return {"import_s": t_imp, "env_and_reset_s": t2 - t1, "first_probe_s": t3 - t2,
            "first_probe_after_import_s": t3 - t1, "scene_build_s": build["s"], "calibration_s": cal["s"],
            "ringdowns": cal["n"], "sim_s": info["last_probe"]["sim_s"]}


MEASURES = {"env": m_env, "vec": m_vec, "start": m_start, "bayes": m_bayes, "pybullet": m_pybullet}


# ------------------------------------------------------------------------------------------- driver


def run_child(path: Path, args: list[str], env: dict, timeout: float = 1800.0) -> dict:
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, str(Path(__file__).resolve()), *args], capture_output=True, text=True,
                          env=env, timeout=timeout, cwd=tempfile.gettempdir())
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed"}
    out = json.loads(done.stdout.strip().splitlines()[-1])
    out["process_wall_s"] = wall
    return out


def run_cli_fit(csv: Path, forward: str, env: dict) -> dict:
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "plate_env", "fit", str(csv), "--forward", forward, "--json"],
                          capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(), timeout=1800)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        return {"error": (done.stderr or done.stdout).strip()[-300:], "cli_s": wall}
    out = json.loads(done.stdout.strip().splitlines()[-1])
    return {"cli_s": wall, "ok": out.get("ok"), "omega_n": out.get("omega_n_rad_s"),
            "stderr_lines": [line for line in done.stderr.splitlines() if line.startswith("plate-env:")][:3]}


def measure_steps(path: Path, args, csv: Path, cache: Path):
    """Every measurement on one tree, as ``(name, thunk)`` steps (the driver interleaves the trees step by step, so
    both see the same load). Its processes share one disk cache (``PLATE_ENV_CACHE_DIR``), empty at the start: the
    ``*_cold_cache`` figures are a first use on a machine, the others a later one (a tree without the disk cache
    computes both the same way)."""
    env = dict(os.environ, PYTHONPATH=str(path), PLATE_ENV_CACHE_DIR=str(cache))
    q = ["--quick"] if args.quick else []
    only = set(args.only.split(",")) if args.only else None
    for label, name in (("start_cold_cache", "start"), ("start", "start"), ("env", "env"), ("vec", "vec"),
                        ("bayes", "bayes")):
        if only is None or label in only:
            yield label, lambda name=name: run_child(path, ["--measure", name, *q], env)

    def vec2() -> dict:  # two vector-env processes at once: the aggregate of the machine's 2 cores
        procs = [subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--measure", "vec", *q],
                                  stdout=subprocess.PIPE, text=True, env=env, cwd=tempfile.gettempdir())
                 for _ in range(2)]
        outs = [json.loads(p.communicate()[0].strip().splitlines()[-1]) for p in procs]
        return {"steps_per_s": sum(o["steps_per_s"] for o in outs), "per_process": [o["steps_per_s"] for o in outs]}

    if only is None or "vec2" in only:
        yield "vec2", vec2
    names = json.loads((path / "plate_env" / "data" / "forward_models.json").read_text())
    if only is not None and "fit" not in only:
        names = []

    def fit(fm: str) -> dict:
        first = run_cli_fit(csv, fm, env)
        cli = run_cli_fit(csv, fm, env)
        inproc = run_child(path, ["--measure", "fit", "--forward", fm, "--csv", str(csv)], env)
        return {**cli, "cli_s_cold_cache": first["cli_s"], "progress": first.get("stderr_lines"),
                **{k: inproc.get(k) for k in ("import_s", "identify_s", "second_identify_s")}}

    for fm in sorted(names):
        yield f"fit/{fm}", lambda fm=fm: fit(fm)
    if not args.no_pybullet and (only is None or "pybullet" in only):
        yield "pybullet_cold_cache", lambda: run_child(path, ["--measure", "pybullet"], env)
        yield "pybullet", lambda: run_child(path, ["--measure", "pybullet"], env)


#: (label, path in a tree's results, unit, better is "higher" or "lower", the issue's goal)
FIGURES = [
    ("atlas env, one env incl. episode ends", ("env", "steps_per_s"), "steps/s", "higher", ">= 10000"),
    ("  the same per CPU second of the process", ("env", "steps_per_cpu_s"), "steps/s", "higher", ""),
    ("SB3 vec env (16, batched), one process", ("vec", "steps_per_s"), "steps/s", "higher", ""),
    ("  the same per CPU second of the process", ("vec", "steps_per_cpu_s"), "steps/s", "higher", ""),
    ("SB3 vec env (16, batched), two processes (2 cores)", ("vec2", "steps_per_s"), "steps/s", "higher",
     ">= 50000"),
    ("first step after gym.make (make + reset + step)", ("start", "make_to_first_step_s"), "s", "lower", "<= 0.05"),
    ("  the same, first use on the machine (empty disk cache)", ("start_cold_cache", "make_to_first_step_s"), "s",
     "lower", ""),
    ("first episode end (the stop step)", ("start", "first_episode_end_s"), "s", "lower", ""),
    ("  the same, first use on the machine (empty disk cache)", ("start_cold_cache", "first_episode_end_s"), "s",
     "lower", ""),
    ("import gymnasium + plate_env", ("start", "import_s"), "s", "lower", ""),
    ("bayes, per decision", ("bayes", "s_per_decision"), "s", "lower", "<= 0.02"),
    ("  the same in CPU seconds of the process", ("bayes", "cpu_s_per_decision"), "s", "lower", ""),
    ("  the slowest decision", ("bayes", "max_s_per_decision"), "s", "lower", ""),
    ("bayes, rest of an episode (probes + estimate)", ("bayes", "rest_of_episode_s"), "s", "lower", ""),
    ("PyBullet first probe after import (env + reset + probe)", ("pybullet", "first_probe_after_import_s"), "s",
     "lower", "<= 3"),
    ("  of which the omega_n calibration (ring-downs)", ("pybullet", "calibration_s"), "s", "lower", ""),
    ("  of which scene builds", ("pybullet", "scene_build_s"), "s", "lower", ""),
    ("  the same, first use on the machine (empty disk cache)", ("pybullet_cold_cache",
                                                                  "first_probe_after_import_s"), "s", "lower", ""),
]


def walk(res: dict, path: tuple):
    """``res[path[0]][path[1]]...``, or None where a key is missing."""
    cur = res
    for k in path:
        if not isinstance(cur, dict) or k not in cur:
            return None
        cur = cur[k]
    return cur


def get(res: dict, path: tuple) -> float | None:
    cur = walk(res, path)
    return cur if isinstance(cur, (int, float)) else None


def get_list(res: dict, path: tuple) -> list | None:
    cur = walk(res, path)
    return cur if isinstance(cur, list) else None


def _fit_outcome(r: dict) -> str:
    """What a timed ``plate-env fit`` answered: the estimate in pi rad/s, or that it failed (a timing of a failed
    command is not the figure the issue asks for)."""
    if "error" in r:
        return "failed (" + r["error"].strip().splitlines()[-1][-80:] + ")"
    if r.get("omega_n") is None:
        return "no estimate" if r else "n/a"
    return f"{r['omega_n'] / math.pi:.2f} pi"


def markdown(doc: dict, source: str = "bench_speed.json") -> str:
    if "current" not in doc["trees"]:  # --no-current: the reference alone, shown as the only column
        doc = {**doc, "commit": doc["ref"], "ref": None, "trees": {"current": doc["trees"]["ref"]}}
    ref, cur = doc["trees"].get("ref"), doc["trees"]["current"]
    cols = ["figure", "goal"] + ([f"before ({doc['ref']})"] if ref else []) + [f"after ({doc['commit']})"] + \
        (["after / before (x faster)"] if ref else [])
    lines = ["# Speed where users wait (issue 25)", "",
             f"Generated from {source} by `{doc['command']}` ({doc['date_utc']}). Load average (1 min) "
             f"{doc['load_before'][0]:.1f} before, {doc['load_after'][0]:.1f} after, on the shared 2-core machine: "
             "read the ratios (same run, same load), not the seconds.", "",
             "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]

    def fmt(v, unit):
        if v is None:
            return "n/a"
        return f"{v:,.0f}" if unit == "steps/s" else f"{v:.3g}"

    def speedup(b, a, better):
        if a is None or b is None or a <= 0 or b <= 0:
            return ""
        return f"{(a / b if better == 'higher' else b / a):.3g}"

    rows = list(FIGURES)
    for fm in sorted(cur.get("fit", {})):
        rows.append((f"`plate-env fit --forward {fm}` (whole command)", ("fit", fm, "cli_s"), "s", "lower", "<= 1"))
        rows.append(("  the same, first use on the machine (empty disk cache)", ("fit", fm, "cli_s_cold_cache"), "s",
                     "lower", ""))
        rows.append((f"  identify alone, {fm}", ("fit", fm, "identify_s"), "s", "lower", ""))
    for label, path, unit, better, goal in rows:
        b = get(ref, path) if ref else None
        a = get(cur, path)
        if a is None and b is None and doc.get("only"):  # not measured in this run (--only)
            continue
        cells = [f"{label} ({unit})", goal] + ([fmt(b, unit)] if ref else []) + [fmt(a, unit)] + \
            ([speedup(b, a, better)] if ref else [])
        lines.append("| " + " | ".join(cells) + " |")
    bp, ap_ = (get_list(ref, ("bayes", "probes")) if ref else None), get_list(cur, ("bayes", "probes"))
    if bp is not None and ap_ is not None:
        same = sum(x == y for x, y in zip(bp, ap_, strict=False))
        lines += ["", f"bayes: the same probes (f_p, A_p) in {same} of {max(len(bp), len(ap_))} episodes before and "
                  "after (same seeds)."]
    fits = [f"`{fm}`: " + ", ".join(f"{lab} {_fit_outcome(t.get('fit', {}).get(fm, {}))}"
                                    for lab, t in (("before", ref), ("after", cur)) if t is not None)
            for fm in sorted(cur.get("fit", {}))]
    if fits:
        lines += ["", f"The fit timed: {SWEEP_POINTS}; what each command answered: " + "; ".join(fits) + "."]
    lines += ["", "Kernel figures (the point-mass kernel) are measured by the kernel's own benchmark.", ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", default=None, help="git revision to measure as 'before' (e.g. 284a76f)")
    ap.add_argument("--quick", action="store_true", help="fewer steps and repeats")
    ap.add_argument("--no-pybullet", action="store_true")
    ap.add_argument("--no-current", action="store_true", help="measure only --ref")
    ap.add_argument("--only", default=None, help="comma-separated measurements to run (start_cold_cache, start, env, "
                    "vec, vec2, bayes, fit, pybullet; default all)")
    ap.add_argument("--measure", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--forward", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--csv", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", default=str(RESULTS / "bench_speed"), help="results path without extension")
    args = ap.parse_args()
    if args.measure == "fit":
        print(json.dumps(m_fit_inproc(args.quick, args.forward, args.csv)))
        return
    if args.measure:
        print(json.dumps(MEASURES[args.measure](args.quick)))
        return
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    doc = {"command": "python experiments/bench_speed.py " + " ".join(sys.argv[1:]), "commit": commit +
           ("+dirty" if dirty else ""), "ref": args.ref, "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
           "load_before": list(os.getloadavg()), "trees": {}, "only": args.only}
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        csv = tmp / "sweep.csv"
        csv.write_text(SWEEP_CSV)
        todo = ([("ref", args.ref)] if args.ref else []) + ([] if args.no_current else [("current", None)])
        gens = {}
        for label, ref in todo:
            print(f"{label}: {ref or doc['commit']}", file=sys.stderr, flush=True)
            path = overlay(tree_path(ref if ref or dirty else "HEAD", tmp), tmp)
            gens[label] = measure_steps(path, args, csv, tmp / f"cache-{label}")
            doc["trees"][label] = {"fit": {}}
        for steps in zip(*gens.values(), strict=True):  # one measurement on every tree, then the next
            for label, (name, thunk) in zip(gens, steps, strict=True):
                out = thunk()
                if name.startswith("fit/"):
                    doc["trees"][label]["fit"][name[4:]] = out
                else:
                    doc["trees"][label][name] = out
                print(f"  {label} {name}: {out}", file=sys.stderr, flush=True)
    doc["load_after"] = list(os.getloadavg())
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(doc, indent=1) + "\n")
    out.with_suffix(".md").write_text(markdown(doc, out.with_suffix(".json").name))
    print(markdown(doc, out.with_suffix(".json").name))


if __name__ == "__main__":
    main()
