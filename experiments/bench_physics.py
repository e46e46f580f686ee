"""Speed and accuracy of the tile-link physics: real-time factor, stable time step, dt error, window length.

    python experiments/bench_physics.py [--repeats 5] [--out experiments/results/bench_physics.md]

Prints (and writes as markdown):
1. real-time factor (simulated s per wall s) of one probe and of a batch of 32, median of repeats;
2. the largest stable time step per omega_n (no blow-up on a 25 Hz, 3 deg probe and a still plate);
3. omega_B error of each dt against dt = 2.5e-5 s (the dt -> 0 value) over frequencies and objects;
4. omega_B against the settling and measurement windows (reference: 3 s settle, 6 s measure).
All figures are measured in this one run on a shared machine.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from common import rtf

import plate_env as pe

A3 = 3.0


def probes(objs, freqs, **kw):
    return [pe.ProbeSpec(o, pe.PlateMotion.from_paper(f, A3), **kw) for o in objs for f in freqs]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--model", default="pointmass")
    ap.add_argument("--out", default="experiments/results/bench_physics.md")
    args = ap.parse_args()
    lines = [f"# bench_physics ({args.model})", ""]

    def emit(s=""):
        print(s)
        lines.append(s)

    base = pe.make_physics("tilelink", model=args.model)
    cheese = pe.preset("cheese")
    # 1. real-time factor
    t0 = time.perf_counter()
    base.run(probes([cheese], [20.0]))
    emit(f"first call in this process (cache load or compile): {time.perf_counter() - t0:.2f} s")
    one = probes([cheese], [20.0])
    batch = [pe.ProbeSpec(cheese.with_(omega_n=(5 + k) * math.pi), pe.PlateMotion.from_paper(18 + 0.1 * k, A3))
             for k in range(32)]
    r1, _ = rtf(base, one, args.repeats)
    r32, bad = rtf(base, batch, args.repeats)
    emit(f"## Real-time factor (dt = {base.dt:g} s, median of {args.repeats})")
    emit("")
    emit("| probes | real-time factor (aggregate) | unstable |")
    emit("|---|---|---|")
    emit(f"| 1 | {r1:.0f}x | 0 |")
    emit(f"| 32 | {r32:.0f}x | {bad} |")
    emit("")
    # 2. largest stable dt per omega_n
    emit("## Largest stable time step per omega_n (25 Hz, 3 deg probe and a still plate)")
    emit("")
    emit("| omega_n [pi rad/s] | largest stable dt [s] |")
    emit("|---|---|")
    dts = [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 6e-4, 8e-4, 1e-3, 1.5e-3]
    blowups = ("non_finite", "runaway_energy", "left_plate", "overturned")
    for wn in (1.4, 3.5, 10, 23, 33, 40, 50):
        obj = pe.ObjectSpec.from_paper(wn, 36.9)
        ok = 0.0
        for dt in dts:
            phys = pe.make_physics("tilelink", model=args.model, dt=dt)
            res = phys.run([pe.ProbeSpec(obj, pe.PlateMotion.from_paper(25, A3)),
                            pe.ProbeSpec(obj, pe.PlateMotion.from_paper(25, 0.0, 0.0))])
            if any(r.reason in blowups for r in res):
                break
            ok = dt
        emit(f"| {wn} | {ok:g} |")
    emit("")
    # 3. dt error
    freqs = [14.0, 18.0, 21.0, 24.0, 26.0]
    objs = [pe.ObjectSpec.from_paper(w, 36.9) for w in (3.5, 10, 23, 33, 50)]
    ref = pe.make_physics("tilelink", model=args.model, dt=2.5e-5).run(probes(objs, freqs))
    emit("## omega_B error against dt = 2.5e-5 s (5 objects 3.5pi-50pi x 5 frequencies 14-26 Hz, 3 deg)")
    emit("")
    emit("| dt [s] | median error | max error | real-time factor (batch) |")
    emit("|---|---|---|---|")
    for dt in (5e-5, 1e-4, 2e-4, 3e-4, 4e-4):
        phys = pe.make_physics("tilelink", model=args.model, dt=dt)
        specs = probes(objs, freqs)
        t0 = time.perf_counter()
        res = phys.run(specs)
        wall = time.perf_counter() - t0
        errs = [abs(r.omega_b_deg_s - q.omega_b_deg_s) / abs(q.omega_b_deg_s)
                for r, q in zip(res, ref, strict=True) if not (r.unstable or q.unstable)]
        emit(f"| {dt:g} | {100 * np.median(errs):.2f} % | {100 * np.max(errs):.2f} % | "
             f"{sum(r.sim_s for r in res) / wall:.0f}x |")
    emit("")
    # 4. windows
    emit("## omega_B against settling / measurement window (10pi and 33pi; 14, 20, 24 Hz)")
    emit("")
    objs = [pe.ObjectSpec.from_paper(w, 36.9) for w in (10, 33)]
    freqs = [14.0, 20.0, 24.0]
    long = base.run(probes(objs, freqs, settle_s=3.0, measure_s=6.0))
    emit("| settle [s] | measure [s] | median diff to 3 s + 6 s | max diff | simulated s per probe |")
    emit("|---|---|---|---|---|")
    for settle, measure in ((0.3, 0.5), (0.5, 1.0), (0.8, 1.5), (1.0, 2.0), (1.5, 3.0)):
        res = base.run(probes(objs, freqs, settle_s=settle, measure_s=measure))
        d = [abs(r.omega_b_deg_s - q.omega_b_deg_s) / abs(q.omega_b_deg_s)
             for r, q in zip(res, long, strict=True) if not (r.unstable or q.unstable)]
        emit(f"| {settle} | {measure} | {100 * np.median(d):.1f} % | {100 * np.max(d):.1f} % | "
             f"{np.mean([r.sim_s for r in res]):.2f} |")
    with open(args.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
