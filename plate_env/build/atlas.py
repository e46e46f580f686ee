"""The atlas builder behind ``plate-env build atlas`` (and ``experiments/build_atlas.py``): probe a physics backend
over a grid, resumably through the project's executor, reduce the repeats to an :class:`~plate_env.surrogate.atlas.
Atlas`, score it against live probes at held-out points, save it with its provenance and the build record.

Grids: a named grid of :data:`GRIDS` (``tilelink``, ``pybullet``), a grid file shipped in ``plate_env/data/grids``
by its stem (``pointmass_m13.6``: the grid of the shipped ``atlas_tilelink_pointmass.npz``), or a path to a grid
file (:class:`~plate_env.build.atlas_grid.AtlasGrid`). ``select`` builds only some nodes of a grid, with the
placements the whole grid would draw for them (every probe's placement is drawn in grid order from one seeded
generator), so a node of a partial build equals that node of the whole build.

The PyBullet grid (``sweeps``): probes run object-major with ascending f_p (the backend carries the sheet over a
sequence of one object's probes), centred, one repeat; the between-placement spread is measured by re-running a
few grid sweeps at other placements (:data:`~plate_env.build.eval_sets.PYBULLET_PLACEMENT_POSES`) and folded into
every grid point's spread.
"""

from __future__ import annotations

import dataclasses
import datetime
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from plate_env.bench.reporting import median_p90
from plate_env.build import eval_sets as bm
from plate_env.build.atlas_grid import AtlasGrid, result_arrays, run_grid
from plate_env.build.provenance import machine
from plate_env.core.files import check_output, check_output_dir, write_text_atomic
from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectSpec
from plate_env.core.probe import PLACEMENT_STD_M, ProbeSpec
from plate_env.identify.inference import fit_sigma_model
from plate_env.identify.lab_calibration_file import package_version
from plate_env.physics.nuisance import Nuisance
from plate_env.run.executor import BackendSpec, make_executor
from plate_env.run.sweeps import run_cached
from plate_env.surrogate.atlas import FILL_SPREAD, Atlas, atlas_file, atlas_from_repeats

#: Named grids.
GRIDS = {
    "tilelink": AtlasGrid(bm.ATLAS_F_HZ, bm.ATLAS_AMPS_DEG, bm.ATLAS_OMEGAS_PI, bm.ATLAS_ALPHAS_DEG, 0.5, 1.0),
    "pybullet": AtlasGrid(bm.PYBULLET_ATLAS_F_HZ, bm.PYBULLET_ATLAS_AMPS_DEG, bm.PYBULLET_ATLAS_OMEGAS_PI,
                          bm.PYBULLET_ATLAS_ALPHAS_DEG, bm.PYBULLET_SETTLE_S, bm.PYBULLET_MEASURE_S),
}
#: Grid axes a selection may name (AtlasGrid.from_dict's keys).
AXES = {"f_p_hz": "f_hz", "a_p_deg": "a_p_deg", "omega_n_pi": "omega_n_pi", "alpha_deg": "alpha_deg"}


def shipped_grids() -> list[str]:
    """The grid files shipped in ``plate_env/data/grids``, by stem."""
    return sorted(p.name.removesuffix(".json") for p in (resources.files("plate_env") / "data" / "grids").iterdir()
                  if p.name.endswith(".json"))


def resolve_grid(name: str) -> AtlasGrid:
    """A named grid, a shipped grid file's stem, or a grid file's path; ValueError naming the choices."""
    if name in GRIDS:
        return GRIDS[name]
    ref = resources.files("plate_env") / "data" / "grids" / f"{name}.json"
    if ref.is_file():
        with resources.as_file(ref) as p:
            return AtlasGrid.from_json(p)
    if Path(name).is_file():
        return AtlasGrid.from_json(name)
    raise ValueError(f"grid {name!r}: not a named grid {sorted(GRIDS)}, a shipped grid {shipped_grids()}, nor a "
                     "grid file")


def select_grid(grid: AtlasGrid, select: dict[str, Sequence[float]]) -> tuple[AtlasGrid, tuple[list[int], ...]]:
    """The sub-grid of the nodes whose axis values are in ``select`` (axis -> values, an axis left out keeps all)
    and its indices into ``grid`` per axis. ValueError for an unknown axis or a value not on the grid."""
    if unknown := set(select) - set(AXES):
        raise ValueError(f"select: unknown axes {sorted(unknown)}; expected {sorted(AXES)}")
    picks = []
    for key, attr in AXES.items():
        axis = getattr(grid, attr)
        if key not in select:
            picks.append(list(range(len(axis))))
            continue
        idx = []
        for v in select[key]:
            hit = [i for i, a in enumerate(axis) if math.isclose(a, float(v), rel_tol=1e-9)]
            if not hit:
                raise ValueError(f"select {key} = {v!r}: not on the grid ({list(axis)})")
            idx.append(hit[0])
        picks.append(sorted(set(idx)))
    sub = dataclasses.replace(grid, **{attr: tuple(getattr(grid, attr)[i] for i in ix)
                                       for attr, ix in zip(AXES.values(), picks, strict=True)})
    return sub, tuple(picks)


@dataclass(frozen=True)
class AtlasJob:
    """One atlas build. ``grid_name`` names the grid (:func:`resolve_grid`), ``out`` the .npz to write (default
    the shipped name, ``atlas_<physics>_<model>.npz``, in the working directory), ``cache_dir`` where finished
    chunks are appended (re-running resumes), ``report`` an optional markdown report, ``record`` the build record
    (:func:`plate_env.build.provenance.build_record`), stored in the atlas's provenance as ``built_by``."""

    physics: str = "tilelink"
    model: str = "pointmass"
    grid_name: str | None = None
    repeats: int = 3
    seed: int = 0
    held_out: int | None = None
    nuisance: Nuisance | None = None
    options: dict = field(default_factory=dict)
    executor: str = "local"
    chunk: int | None = None
    name: str | None = None
    out: str | None = None
    cache_dir: str = "."
    report: str | None = None
    select: dict = field(default_factory=dict)
    record: dict = field(default_factory=dict)
    #: progress of the probes (plate_env.core.progress: a bar in a terminal, a few plain lines otherwise); False: none
    progress: bool = True

    def grid_label(self) -> str:
        return self.grid_name or ("pybullet" if self.physics == "pybullet" else "tilelink")

    def out_path(self, model: str) -> str:
        """The atlas file this job writes (``model``: the name its atlas is filed under, :func:`make_backend`)."""
        return self.out or (atlas_file(self.physics, model) if not self.name else f"atlas_{self.name}.npz")

    def n_held(self) -> int:
        return self.held_out if self.held_out is not None else (0 if self.physics == "pybullet" else 120)


def make_backend(physics_name: str, model: str, nuisance: Nuisance | None = None, **kw) -> tuple[BackendSpec, str]:
    """The backend's description, and the model name its atlas is filed under (tilelink: the model; else the
    physics name). ``nuisance``: tile-link joint and contact values other than the defaults."""
    if physics_name == "tilelink":
        options = nuisance.tilelink_options(model) if nuisance is not None else {"model": model}
        return BackendSpec.of("tilelink", **options, **kw), model
    if physics_name == "pybullet":
        return BackendSpec.of("pybullet", n_workers=1, **kw), physics_name
    return BackendSpec.of(physics_name), physics_name


def build_atlas(job: AtlasJob) -> tuple[Atlas, str, list[str]]:
    """Run ``job``: the atlas, the path it was saved to and the report's lines (also written to ``job.report``)."""
    grid = resolve_grid(job.grid_label())
    if job.select:
        grid, picks = select_grid(grid, job.select)
    else:
        picks = None
    backend, model = make_backend(job.physics, job.model, job.nuisance, **job.options)
    tag = job.name or f"{job.physics}_{model}"
    check_output_dir(job.cache_dir, "--cache-dir")  # before any probe: a build that cannot resume is refused
    check_output(job.out_path(model), "--out")
    if job.report:
        check_output(job.report, "--report")
    physics = backend.build()  # read-only here: its settings for the provenance (the executor runs its own)
    executor = make_executor(job.executor, backend)
    t0 = time.perf_counter()
    try:
        full = resolve_grid(job.grid_label())
        res = run_grid(backend, full, job.repeats, job.seed, Path(job.cache_dir) / f"atlas_{tag}.jsonl",
                       executor=executor, chunk=job.chunk, placed=True, sweeps=job.physics == "pybullet",
                       nodes=picks, progress=job.progress)
        return _finish(job, grid, backend, physics, model, tag, res, executor, t0)
    finally:
        executor.close()
        physics.close()


def _f_range(f) -> str:
    step = f[1] - f[0] if len(f) > 1 else 0.0
    return f"{f[0]:g}:{f[-1]:g}:{step:g}"


def _provenance(job: AtlasJob, grid: AtlasGrid, backend: BackendSpec, physics) -> dict:
    return {"grid": job.grid_label(), "f_p_hz": _f_range(grid.f_hz), "a_p_deg": grid.a_p_deg,
            "omega_n_pi": grid.omega_n_pi, "alpha_deg": grid.alpha_deg, "repeats": job.repeats, "seed": job.seed,
            "b_p_mm": grid.b_p_mm, "mass_g": grid.mass_g, "diameter_mm": grid.diameter_mm,
            "dt_s": physics.dt, "ramp_s": 0.2, "settle_s": grid.settle_s,
            "measure_s": grid.measure_s,
            "backend": {"name": backend.name, "options": {k: repr(v) for k, v in backend.options}},
            "placement": (f"yaw U(0, pi/2), offset N(0, {PLACEMENT_STD_M * 1e3:g} mm) per axis"
                          if job.physics != "pybullet" else
                          "centred (ProbeSpec initial_yaw 0, initial_offset (0, 0)); sweeps per object, ascending f_p, "
                          f"sequence_len {physics.sequence_len}"),
            "plate_env": package_version(), "date": datetime.date.today().isoformat(),
            **({"select": {k: list(v) for k, v in job.select.items()}} if job.select else {}),
            "built_by": job.record, "machine": machine()}


def _finish(job, grid, backend, physics, model, tag, res, executor, t0) -> tuple[Atlas, str, list[str]]:
    f, amps, ws, als = grid.f_hz, grid.a_p_deg, grid.omega_n_pi, grid.alpha_deg
    omega, se, un = result_arrays(res)
    provenance = _provenance(job, grid, backend, physics)
    study_lines: list[str] = []
    floor_abs = floor_rel = None
    if job.grid_label() == "pybullet":
        grid_res = {(ws[i_w], als[i_al], f[i_f]): res[i_f, 0, i_w, i_al, 0]
                    for i_f, i_w, i_al in np.ndindex(len(f), len(ws), len(als))}
        rows, floor_abs, floor_rel = placement_spread(job, grid_res, grid, executor)
        provenance["spread_floor"] = {"abs_deg_s": floor_abs, "rel": floor_rel,
                                      "poses": bm.PYBULLET_PLACEMENT_POSES,
                                      "objects": bm.PYBULLET_PLACEMENT_OBJECTS}
        study_lines = _study_table(rows, floor_abs, floor_rel)
    build_s = time.perf_counter() - t0
    atlas = atlas_from_repeats(job.physics, model, f, amps, np.array(ws) * math.pi, np.radians(als), omega,
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
    n_held = job.n_held()
    if n_held > 0:
        held_lines, sigma_model = _held_out(job, backend, atlas, grid, tag, n_held, executor)
        atlas = dataclasses.replace(atlas, provenance={**provenance, "sigma_model_deg_s": sigma_model,
                                                       "sigma_model_from": f"{n_held} live probes at held-out points"})
    out = job.out_path(model)
    atlas.save(out)
    lines = [f"# Response atlas: {job.physics} / {model}", "",
             f"Grid `{job.grid_label()}`: {len(f)} frequencies ({_f_range(f)} Hz) x A_p {amps} deg x {len(ws)} "
             f"omega_n ({ws[0]}pi-{ws[-1]}pi) x alpha {als} deg x {job.repeats} repeats = {res.size} probes; "
             f"windows 0.2 s ramp + {grid.settle_s} s settle + {grid.measure_s} s measure. File: `{out}` "
             f"({Path(out).stat().st_size / 1e3:.0f} kB). Regenerate: `{job.record.get('command', '?')}`.", "",
             f"Share of unstable probes in the grid: {un.mean():.1%}. Build wall time (this run, grid and placement "
             f"study, cache hits excluded, executor `{job.executor}`): {build_s / 60:.1f} min.", ""]
    if job.grid_label() == "pybullet":
        lines += _grid_table(f, ws, als, omega, un), ""
        lines += study_lines
    if n_held > 0:
        lines += held_lines
    else:
        lines += ["Held-out error: not scored in this build (for the PyBullet atlas: on the identification sweeps "
                  "of held-out objects, `experiments/evaluate_pybullet.py`)."]
    if job.report:
        write_text_atomic(job.report, "\n".join(lines) + "\n", "--report")
    return atlas, str(out), lines


def placement_spread(job: AtlasJob, grid_res: dict, grid: AtlasGrid, executor=None):
    """Sweeps of a few grid objects re-run at other initial placements; returns (rows, abs floor, rel floor).

    rows: (omega_pi, alpha_deg, f, [omega_B per placement, None if unstable]). The floors are the medians of the
    between-placement standard deviation (deg/s) and of that deviation over |mean|, over points with >= 2 stable.
    """
    f, amp = grid.f_hz, grid.a_p_deg[0]
    rows = []
    runs = {}
    for i, pose in enumerate(bm.PYBULLET_PLACEMENT_POSES):
        backend, _ = make_backend(job.physics, "")
        specs = [dataclasses.replace(s, initial_yaw=pose[0], initial_offset=(pose[1], pose[2]))
                 for w, a in bm.PYBULLET_PLACEMENT_OBJECTS
                 for s in bm.sweep_specs(ObjectSpec.from_paper(w, a), f, amp, settle_s=grid.settle_s,
                                         measure_s=grid.measure_s)]
        runs[i] = run_cached(backend, specs, Path(job.cache_dir) / f"atlas_pybullet_pose{i}.jsonl", chunk=len(f),
                             desc=f"placement {i}", executor=executor, progress=job.progress)
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


def held_out_specs(grid: AtlasGrid, n_held: int, seed: int) -> list[ProbeSpec]:
    """The ``n_held`` live probes that score an atlas of ``grid`` built with ``seed``: held-out objects (omega_n,
    alpha off the grid: :data:`plate_env.build.eval_sets.HELD_OUT_OMEGAS_PI` / ``HELD_OUT_ALPHAS_DEG``) at a
    frequency drawn uniformly 0.5 Hz inside the grid's band, each placed at random; deterministic in ``seed``."""
    hrng = np.random.default_rng(seed + 1)
    held = []
    f_lo, f_hi = grid.f_hz[0], grid.f_hz[-1]
    for _ in range(n_held):
        obj = ObjectSpec.from_paper(float(hrng.choice(bm.HELD_OUT_OMEGAS_PI)),
                                    float(hrng.choice(bm.HELD_OUT_ALPHAS_DEG)), mass_g=grid.mass_g,
                                    diameter_mm=grid.diameter_mm)
        held.append(ProbeSpec(obj, PlateMotion.from_paper(float(hrng.uniform(f_lo + 0.5, f_hi - 0.5)),
                                                          float(hrng.choice(grid.a_p_deg)), grid.b_p_mm),
                              settle_s=grid.settle_s, measure_s=grid.measure_s).perturbed(hrng))
    return held


def held_out_score(atlas: Atlas, live: Sequence) -> tuple[list[str], float]:
    """``atlas`` against the live probes ``live`` (ProbeResults at held-out points): a markdown report (median and
    90th-percentile |omega_B error| in deg/s over the stable probes, median |z|, the instability Brier score, the
    share of stability calls agreeing) and the atlas's model error (deg/s,
    :func:`plate_env.identify.inference.fit_sigma_model`). Pure."""
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
    agree = float(np.mean((pu > 0.5) == (unst > 0.5)))  # the atlas's stability call (p_unstable > 1/2) vs live
    err_med, err_p90 = median_p90(err)
    return [f"## Error against {len(live)} live probes at held-out points (off-grid f_p, omega_n, alpha)", "",
            "| stable probes | median abs error [deg/s] | 90th pct [deg/s] | median abs z (error / spread) | "
            "instability Brier score (0.25 = coin) | stability calls agreeing | observed unstable share |",
            "|---|---|---|---|---|---|---|",
            f"| {len(st)} | {err_med:.1f} | {err_p90:.1f} | {np.median(np.abs(z)):.2f} | "
            f"{brier:.3f} | {agree:.2f} | {unst.mean():.2f} |", "",
            f"Model error beyond the spread (maximum likelihood, Student-t, "
            f"`plate_env.identify.inference.fit_sigma_model`): sigma_model = {sigma_model:.2f} deg/s (stored in the "
            "atlas's provenance)."], sigma_model


def _held_out(job, backend, atlas, grid, tag, n_held, executor) -> tuple[list[str], float]:
    """The atlas against live probes at held-out points (:func:`held_out_specs`, cached in the job's cache
    directory as ``atlas_heldout_<tag>.jsonl``), scored by :func:`held_out_score`."""
    cache = Path(job.cache_dir) / f"atlas_heldout_{tag}.jsonl"
    live = run_cached(backend, held_out_specs(grid, n_held, job.seed), cache, desc="held-out", executor=executor,
                      progress=job.progress)
    return held_out_score(atlas, live)


__all__: Sequence[str] = ("AXES", "GRIDS", "AtlasJob", "build_atlas", "held_out_score", "held_out_specs",
                          "make_backend", "resolve_grid", "select_grid", "shipped_grids")
