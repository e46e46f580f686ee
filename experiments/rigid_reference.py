"""The converged rigid limit as reference data: `rigid_limit` at dt = 6.25e-6 s on the issue-26 probe set.

10pi, 23pi, 33pi x alpha 36.9 and 50 deg x f_p 14-30 Hz in 2 Hz steps at A_p 3 deg, B_p 3 mm, the standard probe
windows (ProbeSpec defaults). Placement: centred (yaw 0, no offset; ``placement_seed`` null) by default, as the
earlier converged reference (physics-facts note); ``--placement-seed S`` places probe i by
``ProbeSpec.perturbed(default_rng(S + i))`` instead (with 0.2 mm the rigid limit slipped at 18 and 22 Hz for 10pi,
where the centred disc ran the whole window, which leaves too few stable probes for a first-hump fit). Probes run
``--parallel`` at a time in this process (one thread each) and each finished probe is appended to a JSON-lines
file at once, so an interrupted run keeps what finished and a rerun resumes; ``--collect`` writes
``experiments/results/rigid_reference.json`` from the lines.

``--yaw-offset-mrad Y`` runs the same centred probes with the initial yaw moved by Y mrad into their own files
(``rigid_reference_yaw{Y}mrad.jsonl`` / ``.json``): the reference's own spread of stability calls over a placement
difference no lab controls, against which a model's agreement with the reference is read (issue 34).

Another ``--dt`` also gets its own files (``..._dt{dt}``): the reference's convergence in its step, call by call;
``--keys`` runs only the named probes; ``--model`` another tile-link model (own files, ``..._{model}``).

Usage: ``nice -n 5 python experiments/rigid_reference.py [--dt 6.25e-6] [--limit N] [--yaw-offset-mrad Y]
[--keys K1,K2]`` then ``--collect`` (with the same ``--yaw-offset-mrad`` and ``--dt``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import plate_env as pe
from plate_env.core.probe import ProbeSpec

RESULTS = Path(__file__).resolve().parent / "results"
LINES = RESULTS / "rigid_reference.jsonl"
OUT = RESULTS / "rigid_reference.json"
OMEGA_N_PI = (10.0, 23.0, 33.0)
ALPHA_DEG = (36.9, 50.0)
FREQS_HZ = tuple(float(f) for f in range(14, 31, 2))
A_P_DEG = 3.0
B_P_MM = 3.0
#: Objects run first (the earlier converged reference's three), so an interrupted run has whole sweeps to fit.
PRIORITY = ((10, 36.9), (33, 36.9), (23, 50.0), (10, 50.0), (33, 50.0), (23, 36.9))


def probe_set(seed0: int | None = None, yaw_offset_rad: float = 0.0) -> list[tuple[str, int | None, ProbeSpec]]:
    """(key, placement seed or None for centred, probe) of every reference probe, in a fixed order (object by
    object); ``yaw_offset_rad`` is added to every probe's initial yaw."""
    out = []
    for wn in OMEGA_N_PI:
        for alpha in ALPHA_DEG:
            obj = pe.ObjectSpec.from_paper(wn, alpha)
            for f in FREQS_HZ:
                seed = None if seed0 is None else seed0 + len(out)
                spec = ProbeSpec(obj=obj, motion=pe.PlateMotion.from_paper(f, A_P_DEG, B_P_MM))
                if seed is not None:
                    spec = spec.perturbed(np.random.default_rng(seed))
                if yaw_offset_rad:
                    spec = replace(spec, initial_yaw=spec.initial_yaw + yaw_offset_rad)
                out.append((f"{wn:g}pi_{alpha:g}deg_{f:g}Hz", seed, spec))
    return out


def record(key: str, seed: int | None, res, dt: float, model: str) -> dict:
    """One JSON-ready reference row."""
    s = res.spec
    return {"key": key, "model": model, "dt_s": dt, "omega_n_pi": s.obj.omega_n / math.pi,
            "alpha_deg": math.degrees(s.obj.alpha), "f_p_hz": s.motion.freq_hz, "a_p_deg": A_P_DEG,
            "b_p_mm": B_P_MM, "placement_seed": seed, "initial_yaw_rad": s.initial_yaw,
            "initial_offset_m": list(s.initial_offset), "settle_s": s.settle_s, "measure_s": s.measure_s,
            "omega_b_deg_s": res.omega_b_deg_s, "stderr_deg_s": res.stderr_deg_s, "unstable": res.unstable,
            "reason": res.reason, "sim_s": res.sim_s, "wall_s": res.wall_s,
            "real_time_factor": res.sim_s / res.wall_s if res.wall_s > 0 else None}


def done_keys(path: Path) -> set[str]:
    if not path.exists():
        return set()
    return {json.loads(line)["key"] for line in path.read_text().splitlines() if line.strip()}


REFERENCE_DT = 6.25e-6


def paths(yaw_offset_mrad: float, dt: float = REFERENCE_DT, model: str = "rigid_limit") -> tuple[Path, Path]:
    """(lines, collected json) of the run at this initial-yaw offset, step and tile-link model; (0, 6.25e-6 s,
    rigid_limit) is the reference itself."""
    tags = ([f"yaw{yaw_offset_mrad:g}mrad"] if yaw_offset_mrad else []) + ([f"dt{dt:g}"] if dt != REFERENCE_DT else [])
    tags += [model] if model != "rigid_limit" else []
    if not tags:
        return LINES, OUT
    tag = "_".join(tags)
    return RESULTS / f"rigid_reference_{tag}.jsonl", RESULTS / f"rigid_reference_{tag}.json"


def run(dt: float, limit: int | None, seed0: int | None, pairs: int, yaw_offset_mrad: float = 0.0,
        keys: set[str] | None = None, model: str = "rigid_limit") -> None:
    physics = pe.make_physics("tilelink", model=model, dt=dt)
    lines, _ = paths(yaw_offset_mrad, dt, model)
    done = done_keys(lines)
    rank = {obj: i for i, obj in enumerate(PRIORITY)}
    todo = sorted((p for p in probe_set(seed0, 1e-3 * yaw_offset_mrad)
                   if p[0] not in done and (keys is None or p[0] in keys)),
                  key=lambda p: rank[(round(p[2].obj.omega_n / math.pi), round(math.degrees(p[2].obj.alpha), 1))])
    todo = todo[:limit]
    print(f"{len(done)} done, {len(todo)} to run at dt {dt:g} s, {pairs} at a time", flush=True)
    for start in range(0, len(todo), pairs):
        part = todo[start:start + pairs]
        t0 = time.perf_counter()
        results = physics.run([spec for _, _, spec in part])
        for (key, seed, _), res in zip(part, results, strict=True):
            row = record(key, seed, res, dt, model)
            with lines.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
            print(f"{key}: {res.omega_b_deg_s:.1f} +- {res.stderr_deg_s:.1f} deg/s {res.reason or 'stable'} "
                  f"({time.perf_counter() - t0:.1f} s wall for {len(part)})", flush=True)


def collect(yaw_offset_mrad: float = 0.0, dt: float = REFERENCE_DT, model: str = "rigid_limit") -> None:
    lines, out = paths(yaw_offset_mrad, dt, model)
    rows = {json.loads(line)["key"]: json.loads(line) for line in lines.read_text().splitlines() if line.strip()}
    order = [k for k, _, _ in probe_set() if k in rows]
    desc = __doc__.split("\n")[0] + (f" Initial yaw moved by {yaw_offset_mrad:g} mrad." if yaw_offset_mrad else "")
    desc += f" Run at dt {dt:g} s, not the reference's step." if dt != REFERENCE_DT else ""
    desc += f" Model {model}, not the reference's." if model != "rigid_limit" else ""
    out.write_text(json.dumps({"description": desc, "n_probes": len(order),
                               "probes": [rows[k] for k in order]}, indent=1) + "\n")
    print(f"wrote {out} ({len(order)} probes)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--dt", type=float, default=REFERENCE_DT, help="step (s); another than 6.25e-6 gets its own files")
    ap.add_argument("--model", default="rigid_limit",
                    help="another tile-link model (e.g. pointmass: the contact law's own step sensitivity), own files")
    ap.add_argument("--keys", default="", help="run only these probes (comma-separated keys, e.g. 10pi_50deg_22Hz)")
    ap.add_argument("--limit", type=int, default=None, help="run at most this many of the missing probes")
    ap.add_argument("--placement-seed", type=int, default=None, help="perturbed placements from this seed")
    ap.add_argument("--parallel", type=int, default=2, help="probes per kernel call (one thread each)")
    ap.add_argument("--yaw-offset-mrad", type=float, default=0.0,
                    help="move every probe's initial yaw by this much (mrad), into its own files")
    ap.add_argument("--collect", action="store_true", help="write rigid_reference.json from the finished lines")
    args = ap.parse_args()
    if args.collect:
        collect(args.yaw_offset_mrad, args.dt, args.model)
    else:
        keys = {k for k in args.keys.split(",") if k.strip()} or None
        run(args.dt, args.limit, args.placement_seed, args.parallel, args.yaw_offset_mrad, keys, args.model)


if __name__ == "__main__":
    main()
