"""Skip what a scene doesn't need, measured: each saving's speed-up and its effect on omega_B, one table.

    python experiments/bench_savings.py [--repeats 5] [--cold-repeats 1] [--pybullet]

Savings on tilelink/pointmass (each against the same work done without the saving, in this one run):

* batched probes: a 31-probe sweep in one ``run`` call (numba threads) vs 31 calls of one probe;
* kernel cache: a fresh process's first probe with the on-disk numba cache vs a cold compile
  (``NUMBA_CACHE_DIR`` pointed at an empty directory);
* shorter windows: 0.5 + 1.0 s (default) and 0.3 + 0.5 s, 0.2 + 0.25 s vs 1.5 + 3.0 s (converged);
* coarser time step: dt 2e-4 s (default) and 4e-4 s vs 2.5e-5 s;
* fewer read-backs: yaw/centre recorded every 1 ms (default), 5 ms, 20 ms vs every step (the kernel writes fewer
  samples and Python reads back fewer);
* no trace kept: ``record_trace=False`` (default) vs True (copies of the recorded arrays per result);
* skip the physics: the atlas backend (interpolated table, seeded noise) vs the live probes;
* PyBullet (``--pybullet``, tiny 30-point/layer sheet, fixed spring stiffness): one scene reused by a sequence of
  probes (``sequence_len=8``, default) vs a fresh scene per probe (``sequence_len=1``).

Probe set for the accuracy columns: omega_n = 10pi and 33pi (alpha 36.9 deg) x f_p = 14, 18, 20, 22, 24, 26 Hz at
A_p = 3 deg, B_p = 3 mm, centred disc. Error = |omega_B - omega_B(reference)| / |omega_B(reference)| over probes
stable in both; time = median of ``--repeats`` (cold compile: ``--cold-repeats``). Writes
experiments/results/bench_savings.md.
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
from collections.abc import Callable
from pathlib import Path

import numpy as np

import plate_env as pe
from plate_env.build import eval_sets as bm
from plate_env.core.probe import ProbeResult, ProbeSpec
from plate_env.physics.tilelink.params import DEFAULT_RECORD_INTERVAL_S

SCRIPT = "experiments/bench_savings.py"
A_P_DEG = 3.0
FREQS = (14.0, 18.0, 20.0, 22.0, 24.0, 26.0)


def probe_set(settle_s: float = 0.5, measure_s: float = 1.0, record_trace: bool = False) -> list[ProbeSpec]:
    """The accuracy probe set (12 probes) with the given windows (s)."""
    return [ProbeSpec(pe.ObjectSpec.from_paper(w, 36.9), pe.PlateMotion.from_paper(f, A_P_DEG), settle_s=settle_s,
                      measure_s=measure_s, record_trace=record_trace) for w in (10.0, 33.0) for f in FREQS]


def timed(fn: Callable[[], list[ProbeResult]], repeats: int) -> tuple[float, list[ProbeResult]]:
    """Median wall seconds of ``fn`` over repeats (after one warm call) and its last results."""
    res = fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), res


def errors(res: list[ProbeResult], ref: list[ProbeResult]) -> tuple[float, float, int]:
    """Median and max relative omega_B difference over probes stable in both, and the number of verdict changes."""
    rel = [abs(a.omega_b_deg_s - b.omega_b_deg_s) / abs(b.omega_b_deg_s) for a, b in zip(res, ref, strict=True)
           if not a.unstable and not b.unstable and b.omega_b_deg_s != 0]
    flips = sum(a.unstable != b.unstable for a, b in zip(res, ref, strict=True))
    if not rel:
        return math.nan, math.nan, flips
    return float(np.median(rel)), float(np.max(rel)), flips


COLD_CODE = """
import json, time
t0 = time.perf_counter()
import plate_env as pe
spec = pe.ProbeSpec(pe.ObjectSpec.from_paper(10.0, 36.9), pe.PlateMotion.from_paper(20.0, 3.0))
r = pe.make_physics("tilelink").run([spec])[0]
print(json.dumps({"wall": time.perf_counter() - t0, "omega": r.omega_b_deg_s}))
"""


def first_probe_in_fresh_process(cache_dir: str | None) -> tuple[float, float]:
    """(wall s from interpreter start of imports to the first probe's result, omega_B) in a new process."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    out = subprocess.run([sys.executable, "-c", COLD_CODE], env=env, capture_output=True, text=True, check=True)
    d = json.loads(out.stdout.strip().splitlines()[-1])
    return float(d["wall"]), float(d["omega"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cold-repeats", type=int, default=1)
    ap.add_argument("--pybullet", action="store_true")
    ap.add_argument("--out-dir", default="experiments/results")
    args = ap.parse_args()
    rows: list[str] = []

    def row(saving: str, base: str, fast: str, t_base: float, t_fast: float, err: tuple[float, float, int],
            note: str = "") -> None:
        med, mx, flips = err
        err_txt = "identical" if med == 0 and mx == 0 and flips == 0 else \
            f"{100 * med:.2f} % / {100 * mx:.2f} %" + (f", {flips} verdict changes" if flips else "")
        rows.append(f"| {saving} | {base} | {fast} | {t_base:.3f} | {t_fast:.3f} | {t_base / t_fast:.1f}x | "
                    f"{err_txt} | {note} |")
        print(rows[-1])

    physics = pe.make_physics("tilelink")
    # 1. batched vs one by one
    sweep = bm.sweep_specs(pe.ObjectSpec.from_paper(10.0, 36.9), bm.SWEEP_F_HZ, A_P_DEG)
    t_one, r_one = timed(lambda: [physics.run([s])[0] for s in sweep], args.repeats)
    t_bat, r_bat = timed(lambda: physics.run(sweep), args.repeats)
    row("batched probes", "31 calls of 1 probe", "1 call of 31 probes", t_one, t_bat, errors(r_bat, r_one),
        "2 cores; numba prange threads")
    # 2. kernel cache vs cold compile
    warm = [first_probe_in_fresh_process(None) for _ in range(args.repeats)]
    cold = []
    for _ in range(args.cold_repeats):
        with tempfile.TemporaryDirectory() as tmp:
            cold.append(first_probe_in_fresh_process(tmp))
    t_warm = statistics.median(w for w, _ in warm)
    t_cold = statistics.median(w for w, _ in cold)
    same = all(o == warm[0][1] for _, o in warm + cold)
    row("kernel cache", "cold compile (empty NUMBA_CACHE_DIR)", "on-disk numba cache", t_cold, t_warm,
        (0.0, 0.0, 0) if same else (math.nan, math.nan, 0),
        f"fresh process, imports + first probe; n = {args.cold_repeats} cold, {args.repeats} warm")
    # 3. windows
    t_ref, r_ref = timed(lambda: physics.run(probe_set(1.5, 3.0)), args.repeats)
    for settle, measure in ((0.5, 1.0), (0.3, 0.5), (0.2, 0.25)):
        t, r = timed(lambda s=settle, m=measure: physics.run(probe_set(s, m)), args.repeats)
        row("shorter windows", "1.5 + 3.0 s", f"{settle:g} + {measure:g} s" + (" (default)" if settle == 0.5 else ""),
            t_ref, t, errors(r, r_ref), "12 probes, one batch")
    # 4. time step
    fine = pe.make_physics("tilelink", dt=2.5e-5)
    t_ref, r_ref = timed(lambda: fine.run(probe_set()), max(1, args.repeats // 2))
    for dt in (2e-4, 4e-4):
        coarse = pe.make_physics("tilelink", dt=dt)
        t, r = timed(lambda c=coarse: c.run(probe_set()), args.repeats)
        row("coarser time step", "dt 2.5e-5 s", f"dt {dt:g} s" + (" (default)" if dt == 2e-4 else ""), t_ref, t,
            errors(r, r_ref), "12 probes, one batch")
    # 5. fewer read-backs (the record interval is a backend option, part of the sweep cache key)
    every_step = pe.make_physics("tilelink", record_interval_s=physics.dt)
    t_ref, r_ref = timed(lambda: every_step.run(probe_set()), args.repeats)
    for interval in (1e-3, 5e-3, 2e-2):
        sparse = pe.make_physics("tilelink", record_interval_s=interval)
        t, r = timed(lambda p=sparse: p.run(probe_set()), args.repeats)
        row("fewer read-backs", f"record every step ({physics.dt:g} s)",
            f"every {interval * 1e3:g} ms" + (" (default)" if interval == DEFAULT_RECORD_INTERVAL_S else ""), t_ref,
            t, errors(r, r_ref), "yaw/centre samples; omega_B interpolated at period boundaries")
    # 6. no trace
    t_tr, r_tr = timed(lambda: physics.run(probe_set(record_trace=True)), args.repeats)
    t_no, r_no = timed(lambda: physics.run(probe_set()), args.repeats)
    row("no trace kept", "record_trace=True", "record_trace=False (default)", t_tr, t_no, errors(r_no, r_tr),
        "per-result array copies")
    # 7. atlas instead of live physics
    atlas = pe.make_physics("atlas")
    t_live, r_live = timed(lambda: physics.run(probe_set()), args.repeats)
    t_at, r_at = timed(lambda: atlas.run(probe_set()), args.repeats)
    row("skip the physics", "live tilelink probes", "atlas backend", t_live, t_at, errors(r_at, r_live),
        "atlas: interpolated mean + seeded noise; for RL training, not for measurement")
    # 8. pybullet scene reuse
    if args.pybullet:
        specs = [ProbeSpec(pe.ObjectSpec.from_paper(10.0, 36.9), pe.PlateMotion.from_paper(f, A_P_DEG),
                           settle_s=0.2, measure_s=0.3) for f in (18.0, 22.0, 26.0)]
        reps = max(1, args.repeats // 3)
        fresh = pe.make_physics("pybullet", n_layer=30, dt=8e-4, sequence_len=1, k_elastic=100.0)
        reuse = pe.make_physics("pybullet", n_layer=30, dt=8e-4, sequence_len=8, k_elastic=100.0)
        t_f, r_f = timed(lambda: fresh.run(specs), reps)
        t_r, r_r = timed(lambda: reuse.run(specs), reps)
        fresh.close()
        reuse.close()
        row("pybullet scene reuse", "fresh scene per probe", "one scene, 3 probes in sequence", t_f, t_r,
            errors(r_r, r_f), "tiny sheet (60 nodes), dt 8e-4 s; reuse also changes the start state")
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = ["# Savings: speed-up and effect on omega_B", "",
          f"Regenerate: `python {SCRIPT} --repeats {args.repeats} --cold-repeats {args.cold_repeats}"
          + (" --pybullet" if args.pybullet else "") + "`. tilelink/pointmass unless said; times are medians of "
          f"{args.repeats} repeats in this run on a shared 2-core machine. Error column: median / max relative "
          "omega_B difference against the row's baseline over probes stable in both (10pi and 33pi, 14-26 Hz, "
          "3 deg), and stable/unstable verdicts that changed.", "",
          "| saving | baseline | with the saving | baseline time [s] | time [s] | speed-up | omega_B error (median / "
          "max) | note |", "|---|---|---|---|---|---|---|---|"] + rows
    (out / "bench_savings.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
