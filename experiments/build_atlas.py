"""Build the response atlas of a physics backend and measure its error against live probes at held-out points.

    python experiments/build_atlas.py [--physics tilelink] [--model pointmass] [--repeats 3] [--seed 0]

Grid (plate_env.benchmarks): f_p 10-40 Hz x A_p {3, 12} deg x 16 omega_n (1.4pi-40pi, log-spaced) x 5 alpha
(28-60 deg), each point repeated with the disc placed at a random yaw and offset (seeded). Batched, resumable
(probes are appended to experiments/cache/atlas_*.jsonl as they finish; Ctrl-C and re-run resumes), with a
progress bar. Writes plate_env/data/atlas_<physics>_<model>.npz and experiments/results/atlas_<physics>_<model>.md.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os

import numpy as np

import plate_env as pe
from plate_env import benchmarks as bm
from plate_env.atlas import atlas_file, atlas_from_repeats
from plate_env.sweeps import run_cached


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--physics", default="tilelink")
    ap.add_argument("--model", default="pointmass")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--held-out", type=int, default=120, help="live probes at held-out points to score the atlas")
    args = ap.parse_args()
    physics = pe.make_physics(args.physics, **({"model": args.model} if args.physics == "tilelink" else {}))
    rng = np.random.default_rng(args.seed)
    f, amps, ws, als = bm.ATLAS_F_HZ, bm.ATLAS_AMPS_DEG, bm.ATLAS_OMEGAS_PI, bm.ATLAS_ALPHAS_DEG
    shape = (len(f), len(amps), len(ws), len(als), args.repeats)
    specs = []
    for idx in np.ndindex(shape):
        i_f, i_a, i_w, i_al, _ = idx
        base = pe.ProbeSpec(pe.ObjectSpec.from_paper(ws[i_w], als[i_al]), pe.PlateMotion.from_paper(f[i_f], amps[i_a]))
        specs.append(base.perturbed(rng))
    tag = f"{args.physics}_{args.model}"
    res = run_cached(physics, specs, f"experiments/cache/atlas_{tag}.jsonl", chunk=128, desc="atlas")
    omega = np.array([r.omega_b_deg_s for r in res]).reshape(shape)
    se = np.array([r.stderr_deg_s for r in res]).reshape(shape)
    un = np.array([r.unstable for r in res]).reshape(shape)
    atlas = atlas_from_repeats(args.physics, args.model, f, amps, np.array(ws) * math.pi, np.radians(als), omega,
                               se, un, provenance={"f_p_hz": "10:40:1", "a_p_deg": amps, "omega_n_pi": ws,
                                                   "alpha_deg": als, "repeats": args.repeats, "seed": args.seed,
                                                   "b_p_mm": 3.0, "dt_s": getattr(physics, "dt", None),
                                                   "settle_s": 0.5, "measure_s": 1.0,
                                                   "placement": "yaw U(0, pi/2), offset N(0, 1 mm) per axis",
                                                   "plate_env": pe.__version__,
                                                   "date": datetime.date.today().isoformat()})
    out = f"plate_env/data/{atlas_file(args.physics, args.model)}"
    atlas.save(out)
    # held-out points: off-grid frequency, omega_n and alpha
    hrng = np.random.default_rng(args.seed + 1)
    held = []
    for _ in range(args.held_out):
        obj = pe.ObjectSpec.from_paper(float(hrng.choice(bm.HELD_OUT_OMEGAS_PI)),
                                       float(hrng.choice(bm.HELD_OUT_ALPHAS_DEG)))
        held.append(pe.ProbeSpec(obj, pe.PlateMotion.from_paper(float(hrng.uniform(10.5, 39.5)),
                                                                float(hrng.choice(amps)))).perturbed(hrng))
    live = run_cached(physics, held, f"experiments/cache/atlas_heldout_{tag}.jsonl", desc="held-out")
    rows = []
    for r in live:
        mu, s, p = atlas.predict(r.spec.motion.freq_hz, r.spec.motion.a_p_deg, r.spec.obj.omega_n, r.spec.obj.alpha)
        rows.append((r.unstable, r.omega_b_deg_s, float(mu), float(s), float(p)))
    st = [(y, mu, s) for u, y, mu, s, _ in rows if not u]
    err = np.array([abs(y - mu) for y, mu, _ in st])
    z = np.array([(y - mu) / max(s, 1e-9) for y, mu, s in st])
    pu = np.array([p for *_, p in rows])
    unst = np.array([u for u, *_ in rows], float)
    brier = float(np.mean((pu - unst) ** 2))
    lines = [f"# Response atlas: {args.physics} / {args.model}", "",
             f"Grid: {len(f)} frequencies (10-40 Hz) x A_p {amps} deg x {len(ws)} omega_n ({ws[0]}pi-{ws[-1]}pi) x "
             f"alpha {als} deg x {args.repeats} repeats = {len(specs)} probes. File: `{out}` "
             f"({os.path.getsize(out) / 1e3:.0f} kB). Regenerate: `python experiments/build_atlas.py`.", "",
             f"Share of unstable probes in the grid: {un.mean():.1%}.", "",
             f"## Error against {len(live)} live probes at held-out points (off-grid f_p, omega_n, alpha)", "",
             "| stable probes | median abs error [deg/s] | 90th pct [deg/s] | median abs z (error / spread) | "
             "instability Brier score (0.25 = coin) | observed unstable share |",
             "|---|---|---|---|---|---|",
             f"| {len(st)} | {np.median(err):.1f} | {np.percentile(err, 90):.1f} | {np.median(np.abs(z)):.2f} | "
             f"{brier:.3f} | {unst.mean():.2f} |"]
    path = f"experiments/results/atlas_{tag}.md"
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
