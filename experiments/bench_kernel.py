"""Point-mass kernel v1 (dense damper, the numbers the shipped atlases were built with) against v2 (grid layout,
mirror-parity damper blocks), in one run.

    python experiments/bench_kernel.py [--repeats 7] [--out experiments/results/bench_kernel]

v1 is the code of main at 284a76f, unchanged (``plate_env/physics/tilelink/kernels.py``), selected with
``TileLinkPhysics(kernel="v1")``. Prints and writes ``<out>.json`` and ``<out>.md``:

1. real-time factor (simulated s / s) of one probe and, aggregate, of a batch of 32 on all cores: median of
   ``--repeats`` runs, the two kernels alternating so both see the same load; by wall time and by the
   process's CPU time (on a shared machine the wall time mostly measures the other processes);
2. omega_B of v2 minus v1 per probe, in units of v1's standard error, over 10pi/23pi/33pi x 14-30 Hz x
   alpha 36.9/50 deg at A_p = 3 deg: max and median, and whether any probe's status differs.
The load (``uptime``) before and after is recorded: ratios from this one run matter more than seconds.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import time

import plate_env as pe

KERNELS = ("v1", "v2")


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def rates(physics: dict, specs: list, repeats: int) -> dict:
    """Median real-time factors (wall and CPU) of running ``specs`` as one batch, kernels alternating."""
    wall: dict = {k: [] for k in physics}
    cpu: dict = {k: [] for k in physics}
    sim = None
    for _ in range(repeats):
        for k, phys in physics.items():
            t0, c0 = time.perf_counter(), time.process_time()
            res = phys.run(specs)
            wall[k].append(time.perf_counter() - t0)
            cpu[k].append(time.process_time() - c0)
            sim = sum(r.sim_s for r in res)
    return {k: {"wall_x": sim / statistics.median(wall[k]), "cpu_x": sim / statistics.median(cpu[k]),
                "wall_s": wall[k], "cpu_s": cpu[k]} for k in physics} | {"simulated_s": sim}


def omega_grid() -> list:
    freqs = (14.0, 18.0, 22.0, 26.0, 30.0)
    return [pe.ProbeSpec(pe.ObjectSpec.from_paper(wn, alpha), pe.PlateMotion.from_paper(f, 3.0))
            for wn in (10.0, 23.0, 33.0) for alpha in (36.9, 50.0) for f in freqs]


def compare_omega(physics: dict) -> dict:
    specs = omega_grid()
    res = {k: p.run(specs) for k, p in physics.items()}
    rows, z = [], []
    for s, a, b in zip(specs, res["v1"], res["v2"], strict=True):
        d = b.omega_b_deg_s - a.omega_b_deg_s
        zz = abs(d) / a.stderr_deg_s if a.stderr_deg_s > 0 else (0.0 if d == 0 else math.inf)
        z.append(zz)
        rows.append({"omega_n_pi": round(s.obj.omega_n / math.pi, 3), "alpha_deg": round(math.degrees(s.obj.alpha), 1),
                     "f_hz": s.motion.freq_hz, "v1_deg_s": a.omega_b_deg_s, "v2_deg_s": b.omega_b_deg_s,
                     "se_deg_s": a.stderr_deg_s, "diff_over_se": zz, "v1_status": a.reason, "v2_status": b.reason,
                     "bit_identical": a.omega_b_deg_s == b.omega_b_deg_s})
    return {"rows": rows, "max_diff_over_se": max(z), "median_diff_over_se": statistics.median(z),
            "status_differs": sum(r["v1_status"] != r["v2_status"] for r in rows), "n": len(rows)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default="experiments/results/bench_kernel")
    args = ap.parse_args()
    if args.repeats < 1:
        raise SystemExit(f"--repeats = {args.repeats} must be at least 1")
    out: dict = {"load_before": uptime(), "cores": os.cpu_count()}
    physics = {k: pe.make_physics("tilelink", model="pointmass", kernel=k) for k in KERNELS}
    cheese = pe.preset("cheese")
    one = [pe.ProbeSpec(cheese, pe.PlateMotion.from_paper(20.0, 3.0))]
    batch = [pe.ProbeSpec(cheese.with_(omega_n=(5 + k) * math.pi), pe.PlateMotion.from_paper(18 + 0.1 * k, 3.0))
             for k in range(32)]
    for k, phys in physics.items():  # compile or load the cache outside the timings
        t0 = time.perf_counter()
        phys.run(one)
        phys.run(batch[:2])
        out[f"first_calls_s_{k}"] = time.perf_counter() - t0
    out["one"] = rates(physics, one, args.repeats)
    out["batch32"] = rates(physics, batch, args.repeats)
    out["omega"] = compare_omega(physics)
    out["load_after"] = uptime()
    lines = ["# bench_kernel: point-mass kernel v1 against v2 (one run)", "",
             f"Command: `python experiments/bench_kernel.py --repeats {args.repeats}`. Load before: "
             f"`{out['load_before']}`; after: `{out['load_after']}` ({out['cores']} cores, shared).", "",
             f"## Real-time factor (median of {args.repeats}, kernels alternating)", "",
             "| probes | v1 wall | v2 wall | v2/v1 wall | v1 CPU | v2 CPU | v2/v1 CPU |",
             "|---|---|---|---|---|---|---|"]
    for key, label in (("one", "1"), ("batch32", "32 (aggregate)")):
        r = out[key]
        v1, v2 = r["v1"], r["v2"]
        lines.append(f"| {label} | {v1['wall_x']:.0f}x | {v2['wall_x']:.0f}x | {v2['wall_x'] / v1['wall_x']:.2f} | "
                     f"{v1['cpu_x']:.0f}x | {v2['cpu_x']:.0f}x | {v2['cpu_x'] / v1['cpu_x']:.2f} |")
    om = out["omega"]
    lines += ["", "CPU: simulated seconds per second of this process's CPU time (for the batch, summed over its "
              "threads, so per core); wall: per second of wall time, what a user waits.", "",
              f"## omega_B, v2 - v1, in units of v1's standard error ({om['n']} probes)", "",
              f"max {om['max_diff_over_se']:.3g}, median {om['median_diff_over_se']:.3g}; probes whose status "
              f"differs: {om['status_differs']}; bit-identical omega_B: {sum(r['bit_identical'] for r in om['rows'])}"
              f" of {om['n']}.", "",
              "| omega_n [pi] | alpha [deg] | f [Hz] | v1 [deg/s] | v2 [deg/s] | se [deg/s] | abs diff / se | status |",
              "|---|---|---|---|---|---|---|---|"]
    for r in om["rows"]:
        lines.append(f"| {r['omega_n_pi']:g} | {r['alpha_deg']:g} | {r['f_hz']:g} | {r['v1_deg_s']:.4f} | "
                     f"{r['v2_deg_s']:.4f} | {r['se_deg_s']:.4f} | {r['diff_over_se']:.2g} | "
                     f"{r['v1_status'] or 'ok'} / {r['v2_status'] or 'ok'} |")
    text = "\n".join(lines) + "\n"
    print(text)
    with open(args.out + ".json", "w") as fh:
        json.dump(out, fh, indent=1, default=float)
    with open(args.out + ".md", "w") as fh:
        fh.write(text)
    print(f"wrote {args.out}.json and {args.out}.md")


if __name__ == "__main__":
    main()
