"""Throughput of the executors (simulated probe-seconds per wall second) and their per-chunk overhead.

    python experiments/bench_executor.py [--repeats 3] [--no-ray]

For the tile-link point-mass model, the rigid tiles in their rigid limit and the PyBullet sheet: the same probes
run by the ``local`` executor (in-process for the point mass, a process pool with one worker per core for the
others) and by a local Ray with as many CPUs, after one warm-up run each (workers started, numba kernels loaded;
the PyBullet sheet at a fixed stiffness, so no per-worker omega_n calibration is timed: that costs a few ring-downs
once per object and worker); Ray's workers at the driver's niceness (``RAY_worker_niceness=0``; Ray's default is
15). Per-chunk overhead: chunks of one ``atlas`` probe (microseconds of work), so the wall
time per chunk is what the executor adds to each chunk. Medians over ``--repeats`` runs; ``uptime`` is recorded
before each measurement (the machine is shared: rerun on a quiet machine for numbers to quote). Writes
``experiments/results/bench_executor.md``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # noqa: E402 - this process is a driver like any other
# Ray's raylet runs task workers at nice 15 by default; the pool's workers run at the driver's niceness. On a shared
# machine that alone decides the comparison, so Ray's workers run at the driver's niceness here too.
os.environ.setdefault("RAY_worker_niceness", "0")

import argparse
import datetime
import statistics
import subprocess
import time
from pathlib import Path

import plate_env as pe
from plate_env.run.executor import BackendSpec, make_executor
from plate_env.run.sweeps import run_cached

OUT = Path(__file__).resolve().parent / "results" / "bench_executor.md"
CHEESE = pe.ObjectSpec.from_paper(10.0, 36.9)


def probes(n: int, settle: float = 0.5, measure: float = 1.0) -> list[pe.ProbeSpec]:
    """``n`` probes of one object over 14-26 Hz (3 deg)."""
    return [pe.ProbeSpec(CHEESE, pe.PlateMotion.from_paper(14.0 + 12.0 * k / max(n - 1, 1), 3.0), settle_s=settle,
                         measure_s=measure) for k in range(n)]


#: name -> (backend, probes, chunk)
WORKLOADS = {
    "tilelink pointmass": (BackendSpec.of("tilelink"), probes(256), 16),
    "tilelink rigid_limit": (BackendSpec.of("tilelink", model="rigid_limit"), probes(8, 0.3, 0.5), 2),
    "pybullet (182 nodes, dt 4e-4)": (BackendSpec.of("pybullet", k_elastic=11.92, sequence_len=2), probes(8, 0.3, 0.6),
                                      2),
}


def uptime() -> str:
    out = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout
    return out.split("load average:")[-1].strip()


def timed(backend, specs, chunk, executor) -> tuple[float, float]:
    t0 = time.perf_counter()
    res = run_cached(backend, specs, None, chunk=chunk, progress=False, executor=executor)
    return time.perf_counter() - t0, sum(r.sim_s for r in res)


def measure(executor, backend, specs, chunk, repeats) -> dict:
    cold, sim = timed(backend, specs, chunk, executor)  # warm-up: workers, kernels
    walls, loads = [], []
    for _ in range(repeats):
        loads.append(uptime())
        w, _ = timed(backend, specs, chunk, executor)
        walls.append(w)
    wall = statistics.median(walls)
    return {"wall": wall, "cold": cold, "sim": sim, "rate": sim / wall, "loads": loads, "n": len(specs),
            "chunk": chunk}


OVERHEAD_BACKEND = BackendSpec.of("atlas")


def overhead_specs(n_chunks: int = 200) -> list[pe.ProbeSpec]:
    return [pe.ProbeSpec(CHEESE, pe.PlateMotion.from_paper(14.0 + 0.01 * k, 3.0)) for k in range(n_chunks)]


def direct_per_probe(repeats: int) -> float:
    """Median wall seconds of one atlas probe run directly on a built backend (the work inside a chunk)."""
    phys = OVERHEAD_BACKEND.build()
    specs = overhead_specs()
    phys.run(specs[:8])
    walls = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for s in specs:
            phys.run([s])
        walls.append((time.perf_counter() - t0) / len(specs))
    return statistics.median(walls)


def overhead(executor, repeats: int, n_chunks: int = 200) -> tuple[float, list[str]]:
    """Median wall seconds per chunk of one atlas probe."""
    backend = OVERHEAD_BACKEND
    specs = overhead_specs(n_chunks)
    run_cached(backend, specs[:8], None, chunk=1, progress=False, executor=executor)  # warm-up
    walls, loads = [], []
    for _ in range(repeats):
        loads.append(uptime())
        t0 = time.perf_counter()
        run_cached(backend, specs, None, chunk=1, progress=False, executor=executor)
        walls.append((time.perf_counter() - t0) / n_chunks)
    return statistics.median(walls), loads


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-ray", action="store_true")
    ap.add_argument("--only", default=None, help="comma list of workload names to run (default: all)")
    args = ap.parse_args()
    cores = os.cpu_count() or 1
    names = [w for w in WORKLOADS if args.only is None or any(o in w for o in args.only.split(","))]
    rows = []
    ray_ex = None
    t_ray = None
    if not args.no_ray:
        t0 = time.perf_counter()
        ray_ex = make_executor("ray", num_cpus=cores)
        t_ray = time.perf_counter() - t0
    try:
        for name in names:
            backend, specs, chunk = WORKLOADS[name]
            local = make_executor("local", backend)
            try:
                loc = measure(local, backend, specs, chunk, args.repeats)
            finally:
                local.close()
            ray = measure(ray_ex, backend, specs, chunk, args.repeats) if ray_ex else None
            rows.append((name, local.name, loc, ray))
            print(name, local.name, f"{loc['rate']:.2f}", f"{ray['rate']:.2f}" if ray else "-", flush=True)
        over = {}
        direct = direct_per_probe(args.repeats)
        for ex_name in ("inprocess", "pool"):
            ex = make_executor(ex_name)
            try:
                over[ex_name] = overhead(ex, args.repeats)
            finally:
                ex.close()
        if ray_ex:
            over["ray"] = overhead(ray_ex, args.repeats)
    finally:
        if ray_ex:
            ray_ex.close()
    lines = ["# Executors: throughput and per-chunk overhead", "",
             f"Generated {datetime.date.today().isoformat()} by `python experiments/bench_executor.py"
             f"{' --no-ray' if args.no_ray else ''}` on {cores} cores (shared: the load averages before each timed "
             f"run are listed; rerun alone on a quiet machine for numbers to quote). Medians of {args.repeats} runs "
             "after a warm-up run. Throughput: simulated probe-seconds per wall second over the whole batch "
             "(run_cached, no cache file). Local Ray started in "
             + (f"{t_ray:.1f} s." if t_ray is not None else "(not run)."), "",
             "| workload | probes x chunk | simulated s | local executor | local: sim s / wall s | local Ray: sim s / "
             "wall s | Ray / local | first (cold) run local / Ray [s] | load (1/5/15 min) local; Ray |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, lname, loc, ray in rows:
        ratio = f"{ray['rate'] / loc['rate']:.2f}" if ray else "-"
        lines.append(f"| {name} | {loc['n']} x {loc['chunk']} | {loc['sim']:.1f} | {lname} | {loc['rate']:.2f} | "
                     f"{ray['rate']:.2f} | {ratio} | {loc['cold']:.1f} / {ray['cold']:.1f} | "
                     f"{loc['loads'][0]}; {ray['loads'][0]} |" if ray else
                     f"| {name} | {loc['n']} x {loc['chunk']} | {loc['sim']:.1f} | {lname} | {loc['rate']:.2f} | - | "
                     f"- | {loc['cold']:.1f} / - | {loc['loads'][0]} |")
    lines += ["", "Per-chunk overhead: wall time per chunk of one atlas probe (200 chunks, median of runs); the "
              f"probe itself, run directly on a built backend, takes {1e3 * direct:.2f} ms. Added per chunk = wall per "
              "chunk x workers - that direct time (worker time the executor adds to every chunk, whatever its size).",
              "", "| executor | workers | wall ms per chunk | added worker ms per chunk | load |",
              "|---|---|---|---|---|"]
    for ex_name, (sec, loads) in over.items():
        workers = 1 if ex_name == "inprocess" else cores
        lines.append(f"| {ex_name} | {workers} | {1e3 * sec:.2f} | {1e3 * (sec * workers - direct):.2f} | {loads[0]} |")
    OUT.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
