"""Build the response atlas of a physics backend and measure its error against live probes at held-out points.

    python experiments/build_atlas.py [--physics tilelink] [--model pointmass] [--repeats 3] [--seed 0]
    python experiments/build_atlas.py --physics pybullet --repeats 1 [--grid pybullet]
    python experiments/build_atlas.py --model rigid_limit --grid-file grid.json --repeats 2 --executor ray \
        [--name rigid_limit_f10_40] [--held-out 0]

Grids (plate_env.benchmarks), chosen by ``--grid`` (default: ``pybullet`` for ``--physics pybullet``, else
``tilelink``):

* ``tilelink``: f_p 10-40 Hz x A_p {3, 12} deg x 16 omega_n (1.4pi-40pi, log-spaced) x 5 alpha (28-60 deg), each
  point repeated with the disc placed at a random yaw and offset (seeded); windows 0.5 s settle + 1.0 s measure.
  Scored against live probes at held-out (off-grid f_p, omega_n, alpha) points.
* ``pybullet``: f_p 10-26 Hz (2 Hz) x A_p 3 deg x omega_n {5, 7, 10, 14, 20, 28, 33}pi x alpha {30, 40, 50, 60} deg,
  windows 0.3 s settle + 0.6 s measure (recorded in the provenance; the evaluation uses the same). Probes run as
  sweeps per object (ascending f_p, the backend's scene carried over within a sequence, as in the evaluation).
  The grid is run centred (``--repeats 1``: a sweep carries one scene over its probes, which random placements
  would break up). The between-placement spread is measured instead by re-running a few grid sweeps at other
  placements (``ProbeSpec.initial_yaw``/``initial_offset``, one per sweep), and folded into every grid point's
  spread (see below). The
  held-out scoring is done on the identification sweeps (``experiments/evaluate_pybullet.py``).

Or a grid named by data: ``--grid-file`` (JSON, :class:`plate_env.atlas_grid.AtlasGrid`: ``f_p_hz`` as a list or
``"start:stop:step"``, ``a_p_deg``, ``omega_n_pi``, ``alpha_deg``, optional ``settle_s``/``measure_s``), e.g.
``{"f_p_hz": "10:40:1", "a_p_deg": [3], "omega_n_pi": [3.5, 5, ...], "alpha_deg": [30, 40, 50, 60]}``.

Chunks of probes run on ``--executor`` (``plate_env.executor``: ``local`` = in-process for the point-mass model, a
process pool for rigid tiles and PyBullet; ``ray``; ``ray://HOST:PORT``), resumable (each finished chunk is appended
to experiments/cache/atlas_<name>.jsonl as it completes; Ctrl-C and re-run resumes), with a progress bar. Writes
plate_env/data/atlas_<physics>_<model>.npz and experiments/results/atlas_<physics>_<model>.md (<model> = the
backend's ``model`` attribute, else the physics name: ``atlas_pybullet_pybullet`` for PyBullet); ``--name`` files
cache, atlas and report under another name instead (so a new grid does not overwrite the shipped atlas).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import math
import os
import sys
import time

import numpy as np

import plate_env as pe
from plate_env.bench.reporting import median_p90
from plate_env.build import eval_sets as bm
from plate_env.build.atlas_grid import AtlasGrid, result_arrays, run_grid
from plate_env.core.probe import PLACEMENT_STD_M
from plate_env.identify.inference import fit_sigma_model
from plate_env.physics.nuisance import Nuisance
from plate_env.run.executor import BackendSpec, add_executor_argument, make_executor
from plate_env.run.sweeps import run_cached
from plate_env.surrogate.atlas import FILL_SPREAD, atlas_file, atlas_from_repeats

#: Named grids.
GRIDS = {
    "tilelink": AtlasGrid(bm.ATLAS_F_HZ, bm.ATLAS_AMPS_DEG, bm.ATLAS_OMEGAS_PI, bm.ATLAS_ALPHAS_DEG, 0.5, 1.0),
    "pybullet": AtlasGrid(bm.PYBULLET_ATLAS_F_HZ, bm.PYBULLET_ATLAS_AMPS_DEG, bm.PYBULLET_ATLAS_OMEGAS_PI,
                          bm.PYBULLET_ATLAS_ALPHAS_DEG, bm.PYBULLET_SETTLE_S, bm.PYBULLET_MEASURE_S),
}


def make_backend(physics_name: str, model: str, nuisance: Nuisance | None = None, **kw) -> tuple[BackendSpec, str]:
    """The backend's description, and the model name its atlas is filed under (tilelink: the model; else the
    physics name). ``nuisance``: tile-link joint and contact values other than the defaults."""
    if physics_name == "tilelink":
        options = nuisance.tilelink_options(model) if nuisance is not None else {"model": model}
        return BackendSpec.of("tilelink", **options, **kw), model
    if physics_name == "pybullet":
        return BackendSpec.of("pybullet", n_workers=1, **kw), physics_name
    return BackendSpec.of(physics_name), physics_name


def _f_range(f) -> str:
    step = f[1] - f[0] if len(f) > 1 else 0.0
    return f"{f[0]:g}:{f[-1]:g}:{step:g}"


def placement_spread(physics_name: str, grid_res: dict, settle: float, measure: float, f, amp: float,
                     executor=None):
    """Sweeps of a few grid objects re-run at other initial placements; returns (rows, abs floor, rel floor).

    rows: (omega_pi, alpha_deg, f, [omega_B per placement, None if unstable]). The floors are the medians of the
    between-placement standard deviation (deg/s) and of that deviation over |mean|, over points with >= 2 stable.
    """
    rows = []
    runs = {}
    for i, pose in enumerate(bm.PYBULLET_PLACEMENT_POSES):
        backend, _ = make_backend(physics_name, "")
        specs = [dataclasses.replace(s, initial_yaw=pose[0], initial_offset=(pose[1], pose[2]))
                 for w, a in bm.PYBULLET_PLACEMENT_OBJECTS
                 for s in bm.sweep_specs(pe.ObjectSpec.from_paper(w, a), f, amp, settle_s=settle, measure_s=measure)]
        runs[i] = run_cached(backend, specs, f"experiments/cache/atlas_pybullet_pose{i}.jsonl", chunk=len(f),
                             desc=f"placement {i}", executor=executor)
    n = len(f)
    sds, rels = [], []
    for j, (w, a) in enumerate(bm.PYBULLET_PLACEMENT_OBJECTS):
        for k, fk in enumerate(f):
            vals = [grid_res[(w, a, fk)]] + [runs[i][j * n + k] for i in runs]
            ys = [None if r.unstable else r.omega_b_deg_s for r in vals]
            rows.append((w, a, fk, ys))
            st = [y for y in ys if y is not None]
            if len(st) >= 2:
                sd = float(np.std(st, ddof=1))
                sds.append(sd)
                rels.append(sd / max(abs(float(np.mean(st))), 1.0))
    if not sds:
        return rows, 1.0, 0.0
    return rows, float(np.median(sds)), float(np.median(rels))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--physics", default="tilelink")
    ap.add_argument("--model", default="pointmass")
    ap.add_argument("--grid", choices=sorted(GRIDS), default=None,
                    help="named grid (default: pybullet for --physics pybullet, else tilelink)")
    ap.add_argument("--grid-file", default=None, help="a grid as JSON (plate_env.atlas_grid.AtlasGrid); "
                    "overrides --grid")
    ap.add_argument("--name", default=None, help="file cache, atlas and report as atlas_<name> (default: "
                    "<physics>_<model>)")
    ap.add_argument("--chunk", type=int, default=None, help="probes per chunk (default: a sweep for pybullet, "
                    "128 in-process, 16 on workers)")
    add_executor_argument(ap)
    ap.add_argument("--nuisance", default=None, help="tile-link joint/contact values, e.g. "
                    "'zeta_bending=0.05,k_inplane=1000' (plate_env.nuisance.Nuisance fields)")
    ap.add_argument("--backend-option", action="append", default=[], metavar="KEY=VALUE",
                    help="a backend option, e.g. n_layer=150 or dt=4e-4 for pybullet (repeatable)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--held-out", type=int, default=None,
                    help="live probes at held-out points to score the atlas (default 120; 0 for the pybullet grid)")
    args = ap.parse_args()
    grid = args.grid or ("pybullet" if args.physics == "pybullet" else "tilelink")
    spec_grid = AtlasGrid.from_json(args.grid_file) if args.grid_file else GRIDS[grid]
    if args.grid_file:
        grid = args.grid_file
    n_held = args.held_out if args.held_out is not None else (0 if args.physics == "pybullet" else 120)
    nuisance = None
    if args.nuisance:
        try:
            nuisance = Nuisance(**{k.strip(): float(v) for k, v in (kv.split("=") for kv in args.nuisance.split(","))})
        except (TypeError, ValueError) as exc:
            ap.error(f"--nuisance {args.nuisance!r}: {exc}")
    options = {}
    for kv in args.backend_option:
        key, _, value = kv.partition("=")
        try:
            options[key.strip()] = int(value) if value.strip().lstrip("-").isdigit() else float(value)
        except ValueError:
            ap.error(f"--backend-option {kv!r}: expected KEY=NUMBER")
    backend, model = make_backend(args.physics, args.model, nuisance, **options)
    physics = backend.build()  # read-only here: its settings for the provenance (the executor runs its own)
    executor = make_executor(args.executor, backend)
    tag = args.name or f"{args.physics}_{model}"
    t0 = time.perf_counter()
    # object-major order with ascending f_p inside (sweeps) for PyBullet: its backend carries the sheet's state
    # over a sequence of probes of one object with one placement (a new placement starts a new scene); the
    # tile-link order (f_p outermost) is kept as it was. Every probe is placed at random (seeded).
    try:
        res = run_grid(backend, spec_grid, args.repeats, args.seed, f"experiments/cache/atlas_{tag}.jsonl",
                       executor=executor, chunk=args.chunk, placed=True,
                       sweeps=args.physics == "pybullet")
        _finish(args, grid, spec_grid, backend, physics, model, tag, res, executor, t0, n_held)
    finally:
        executor.close()
        physics.close()


def _finish(args, grid, spec_grid, backend, physics, model, tag, res, executor, t0, n_held) -> None:
    f, amps, ws, als = spec_grid.f_hz, spec_grid.a_p_deg, spec_grid.omega_n_pi, spec_grid.alpha_deg
    settle, measure = spec_grid.settle_s, spec_grid.measure_s
    omega, se, un = result_arrays(res)
    n_probes = res.size
    provenance = {"grid": grid, "f_p_hz": _f_range(f), "a_p_deg": amps, "omega_n_pi": ws, "alpha_deg": als,
                  "repeats": args.repeats, "seed": args.seed, "b_p_mm": spec_grid.b_p_mm, "mass_g": spec_grid.mass_g,
                  "diameter_mm": spec_grid.diameter_mm, "dt_s": getattr(physics, "dt", None),
                  "ramp_s": 0.2, "settle_s": settle, "measure_s": measure,
                  "backend": {"name": backend.name, "options": {k: repr(v) for k, v in backend.options}},
                  "placement": (f"yaw U(0, pi/2), offset N(0, {PLACEMENT_STD_M * 1e3:g} mm) per axis"
                                if args.physics != "pybullet" else
                                "centred (ProbeSpec initial_yaw 0, initial_offset (0, 0)); sweeps per object, "
                                "ascending f_p, "
                                f"sequence_len {getattr(physics, 'sequence_len', None)}"),
                  "plate_env": pe.__version__, "date": datetime.date.today().isoformat()}
    study_lines: list[str] = []
    floor_abs = floor_rel = None
    if grid == "pybullet":
        grid_res = {(ws[i_w], als[i_al], f[i_f]): res[i_f, 0, i_w, i_al, 0]
                    for i_f, i_w, i_al in np.ndindex(len(f), len(ws), len(als))}
        rows, floor_abs, floor_rel = placement_spread(args.physics, grid_res, settle, measure, f, amps[0],
                                                      executor=executor)
        provenance["spread_floor"] = {"abs_deg_s": floor_abs, "rel": floor_rel,
                                      "poses": bm.PYBULLET_PLACEMENT_POSES,
                                      "objects": bm.PYBULLET_PLACEMENT_OBJECTS}
        study_lines = _study_table(rows, floor_abs, floor_rel)
    build_s = time.perf_counter() - t0
    atlas = atlas_from_repeats(args.physics, model, f, amps, np.array(ws) * math.pi, np.radians(als), omega,
                               se, un, provenance=provenance)
    if floor_abs is not None:
        # fold the between-placement spread into every grid point with a stable probe:
        # spread = sqrt(own stderr^2 + max(abs floor, rel floor * |mean|)^2)
        n_st = (~un).sum(-1)
        own = np.sqrt(np.where(~un, se ** 2, 0.0).sum(-1) / np.maximum(n_st, 1))
        floor = np.maximum(floor_abs, floor_rel * np.abs(atlas.mean))
        spread = np.where(n_st > 0, np.sqrt(own ** 2 + floor ** 2), FILL_SPREAD)
        atlas = dataclasses.replace(atlas, spread=spread)
    held_lines: list[str] = []
    if n_held > 0:
        held_lines, sigma_model = _held_out(args, backend, atlas, spec_grid, tag, n_held, executor)
        atlas = dataclasses.replace(atlas, provenance={**provenance, "sigma_model_deg_s": sigma_model,
                                                       "sigma_model_from": f"{n_held} live probes at held-out points"})
    out = f"plate_env/data/{atlas_file(args.physics, model) if not args.name else f'atlas_{args.name}.npz'}"
    atlas.save(out)
    lines = [f"# Response atlas: {args.physics} / {model}", "",
             f"Grid `{grid}`: {len(f)} frequencies ({_f_range(f)} Hz) x A_p {amps} deg x {len(ws)} omega_n "
             f"({ws[0]}pi-{ws[-1]}pi) x alpha {als} deg x {args.repeats} repeats = {n_probes} probes; windows "
             f"0.2 s ramp + {settle} s settle + {measure} s measure. File: `{out}` "
             f"({os.path.getsize(out) / 1e3:.0f} kB). Regenerate: `python experiments/build_atlas.py "
             f"{' '.join(sys.argv[1:])}`.", "",
             f"Share of unstable probes in the grid: {un.mean():.1%}. Build wall time (this run, grid and placement "
             f"study, cache hits excluded, executor `{args.executor}`): {build_s / 60:.1f} min.", ""]
    if grid == "pybullet":
        lines += _grid_table(f, ws, als, omega, un), ""
        lines += study_lines
    if n_held > 0:
        lines += held_lines
    else:
        lines += ["Held-out error: scored on the identification sweeps of held-out objects "
                  "(`experiments/evaluate_pybullet.py`, `experiments/results/identification_pybullet*.md`)."]
    path = f"experiments/results/atlas_{tag}.md"
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


def _grid_table(f, ws, als, omega, un) -> str:
    head = "| omega_n, alpha | " + " | ".join(f"{x:g}" for x in f) + " |\n|---|" + "---|" * len(f) + "\n"
    body = []
    for i_w, w in enumerate(ws):
        for i_al, a in enumerate(als):
            cells = [f"{omega[k, 0, i_w, i_al, 0]:.0f}" + ("u" if un[k, 0, i_w, i_al, 0] else "")
                     for k in range(len(f))]
            body.append(f"| {w:g}pi, {a:g} deg | " + " | ".join(cells) + " |")
    return ("omega_B [deg/s] at A_p = 3 deg per grid point (`u`: unstable, value over the periods before "
            "the failure):\n\n" + head + "\n".join(body))


def _study_table(rows, floor_abs, floor_rel) -> list[str]:
    out = ["## Between-placement spread (1 repeat per grid point)", "",
           "The grid has one (centred) run per point, so atlas_from_repeats would fall back to a 1 deg/s spread. "
           f"The sweeps of {bm.PYBULLET_PLACEMENT_OBJECTS} (omega_n pi, alpha deg) were re-run with the disc placed "
           f"at {bm.PYBULLET_PLACEMENT_POSES} (ProbeSpec initial_yaw rad, initial_offset m):", "",
           "| omega_n, alpha | f_p | centred / placements [deg/s] | sd |", "|---|---|---|---|"]
    for w, a, fk, ys in rows:
        st = [y for y in ys if y is not None]
        sd = f"{np.std(st, ddof=1):.1f}" if len(st) >= 2 else "-"
        out.append(f"| {w:g}pi, {a:g} | {fk:g} | " + " / ".join("u" if y is None else f"{y:.0f}" for y in ys)
                   + f" | {sd} |")
    out += ["", f"Median between-placement sd: {floor_abs:.1f} deg/s; median sd / |mean|: {100 * floor_rel:.1f} %. "
            "Folded in: every stable grid point's spread = sqrt(own stderr^2 + max(abs floor, rel floor x |mean|)^2) "
            f"(unstable points keep {FILL_SPREAD:g} deg/s).", ""]
    return out


def _held_out(args, backend, atlas, grid, tag, n_held, executor) -> tuple[list[str], float]:
    """The atlas against live probes at held-out points (off-grid frequency, omega_n and alpha): a report and the
    atlas's model error (deg/s, :func:`plate_env.inference.fit_sigma_model`)."""
    hrng = np.random.default_rng(args.seed + 1)
    held = []
    f_lo, f_hi = grid.f_hz[0], grid.f_hz[-1]
    for _ in range(n_held):
        obj = pe.ObjectSpec.from_paper(float(hrng.choice(bm.HELD_OUT_OMEGAS_PI)),
                                       float(hrng.choice(bm.HELD_OUT_ALPHAS_DEG)), mass_g=grid.mass_g,
                                       diameter_mm=grid.diameter_mm)
        held.append(pe.ProbeSpec(obj, pe.PlateMotion.from_paper(float(hrng.uniform(f_lo + 0.5, f_hi - 0.5)),
                                                                float(hrng.choice(grid.a_p_deg)), grid.b_p_mm),
                                 settle_s=grid.settle_s, measure_s=grid.measure_s).perturbed(hrng))
    live = run_cached(backend, held, f"experiments/cache/atlas_heldout_{tag}.jsonl", desc="held-out",
                      executor=executor)
    rows = []
    for r in live:
        mu, s, p = atlas.predict(r.spec.motion.freq_hz, r.spec.motion.a_p_deg, r.spec.obj.omega_n, r.spec.obj.alpha)
        rows.append((r.unstable, r.omega_b_deg_s, float(mu), float(s), float(p), r.stderr_deg_s))
    st = [(y, mu, s) for u, y, mu, s, _, _ in rows if not u]
    sigma_model = fit_sigma_model(np.array([y - mu for y, mu, _ in st]), np.array([s for *_, s in st]),
                                  np.array([e for u, *_, e in rows if not u]))
    err = np.array([abs(y - mu) for y, mu, _ in st])
    z = np.array([(y - mu) / max(s, 1e-9) for y, mu, s in st])
    pu = np.array([p for *_, p, _ in rows])
    unst = np.array([u for u, *_ in rows], float)
    brier = float(np.mean((pu - unst) ** 2))
    err_med, err_p90 = median_p90(err)
    return [f"## Error against {len(live)} live probes at held-out points (off-grid f_p, omega_n, alpha)", "",
            "| stable probes | median abs error [deg/s] | 90th pct [deg/s] | median abs z (error / spread) | "
            "instability Brier score (0.25 = coin) | observed unstable share |",
            "|---|---|---|---|---|---|",
            f"| {len(st)} | {err_med:.1f} | {err_p90:.1f} | {np.median(np.abs(z)):.2f} | "
            f"{brier:.3f} | {unst.mean():.2f} |", "",
            f"Model error beyond the spread (maximum likelihood, Student-t, `plate_env.inference.fit_sigma_model`): "
            f"sigma_model = {sigma_model:.2f} deg/s (stored in the atlas's provenance)."], sigma_model


if __name__ == "__main__":
    main()
