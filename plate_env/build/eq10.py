"""The Eq. (10) line calibrations of ``plate-env fit --method lorentz``: ``plate-env build calibration eq10 --out
FILE`` writes ``plate_env/data/calibration.json`` (:mod:`plate_env.identify.calibration`), four lines:

- ``tilelink/pointmass/3`` and ``tilelink/pointmass/12``: omega_n on the first-hump f0 of live tile-link point-mass
  sweeps (10-40 Hz, 1 Hz, B_p = 3 mm) of the calibration objects (:data:`~plate_env.build.eval_sets.
  CALIBRATION_OMEGAS_PI` x :data:`~plate_env.build.eval_sets.CALIBRATION_ALPHAS_DEG`, 36 objects) at 3 and 12 deg,
  with the friction model: 2,232 probes, simulated and kept in a sweep cache (a re-run only simulates what is
  missing);
- ``tilelink/rigid_fast/3``: the same fit (first-hump f0, friction model) on the faithful physics (the rigid
  tile-link disc, ``rigid_fast``: ``PlateRotation-v1``'s, the suites ``faithful-v0`` and ``rigid-v0``), of the
  faithful atlas's sweeps (grid ``faithful``, seed 0, 2 repeats, every probe placed on its own) at 3 deg whose
  omega_n node lies in the calibration objects' range (3.5-33 pi): 120 sweeps, 3,720 probes already simulated for
  the atlas. They are an input (:data:`RIGID_FAST_CACHE` in ``--lab-sweeps``), never simulated by the builder:
  the calibration objects simulated centred on rigid_fast made a worse line
  (``experiments/results/eq10_rigid_fast.md``);
- ``lab/lab/3``: the line pooled over three model families at 3 deg (:data:`LAB_SETS`: point mass with each
  object's own joint/contact draw, the rigid-tile limit, the PyBullet sheet), each family's own line kept
  (``model_lines``), so that its intervals include the models' disagreement. The point-mass sweeps (3,720 probes)
  are simulated like the tile-link lines'; the rigid-limit (620 probes) and PyBullet (216 probes) sweeps take
  about a quarter of an hour and hours here, and their last bits depend on the CPU, so they are read from sweep
  caches given as input (a checkout's ``experiments/cache`` holds them) and never simulated by the builder.

Every line records how it was made in its ``provenance``; the build record (command, version, commit, machine)
goes beside the file, ``FILE.provenance.json``, so a rebuild from the same sweeps is the same bytes.
``python experiments/calibrate.py`` compares fit-window rules on the tile-link sweeps and
``python experiments/forward_models.py lorentz`` tests the lab line across models left out; both use these
functions.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from plate_env.build import eval_sets as es_mod
from plate_env.build.eval_sets import EvalSet
from plate_env.core.files import write_text_atomic
from plate_env.core.objects import ObjectSpec
from plate_env.identify.calibration import Calibration, fit_calibration, save_calibrations
from plate_env.run.executor import BackendSpec

#: Plate amplitudes (deg) of the tile-link lines.
TILELINK_AMPS_DEG = (3.0, 12.0)
#: The tile-link lines' backend.
TILELINK = BackendSpec.of("tilelink", model="pointmass")
#: The sweep cache of the tile-link lines' probes (the name ``experiments/calibrate.py`` uses in experiments/cache).
TILELINK_CACHE = "sweeps_tilelink_pointmass.jsonl"
#: The faithful physics' line: its backend, its plate amplitude (deg) and its sweep cache (an input, in --lab-sweeps).
RIGID_FAST = BackendSpec.of("tilelink", model="rigid_fast")
RIGID_FAST_AMP_DEG = 3.0
RIGID_FAST_CACHE = "atlas_faithful.jsonl"
#: The faithful atlas's build the line reads (``plate-env build atlas --grid faithful --repeats 2 --seed 0``).
RIGID_FAST_GRID, RIGID_FAST_REPEATS, RIGID_FAST_SEED = "faithful", 2, 0
#: The sweeps the lab line is pooled over, one evaluation set per model family, at 3 deg.
LAB_SETS = {
    "pointmass": EvalSet("tilelink_pointmass", 120, 400, (3.0,), nuisance=True),
    "rigid": EvalSet("tilelink_rigid_limit", 20, 100, (3.0,)),
    "pybullet": EvalSet("pybullet_pybullet", 24, 600, (3.0,), f_hz=tuple(float(f) for f in range(10, 27, 2)),
                        settle_s=0.3, measure_s=0.6, omega_range_pi=(5.0, 33.0)),
}
#: The lab families the builder simulates when their sweeps are missing (the others are inputs).
LAB_SIMULATED = ("pointmass",)
#: The plate amplitude (deg) of the lab line.
LAB_AMP_DEG = 3.0
#: What ``provenance.build`` of every line names.
BUILD_COMMAND = "plate-env build calibration eq10"


def lab_backend_of(family: str) -> Callable:
    """``backend_of(nuisance)`` for :func:`~plate_env.build.eval_sets.run_eval_set` of a lab family: the point mass
    with an object's joint/contact draw, the rigid-tile limit, or the default PyBullet sheet (its shipped atlas's)."""
    def of(nuisance):
        if family == "pybullet":
            return BackendSpec.of("pybullet", n_workers=1)
        if nuisance is not None:
            return BackendSpec.of("tilelink", **nuisance.tilelink_options("pointmass"))
        return BackendSpec.of("tilelink", model="rigid_limit" if family == "rigid" else family)
    return of


def tilelink_specs(a_p_deg: float) -> list:
    """The calibration objects' sweeps at one amplitude, object-major (31 probes each)."""
    objs = es_mod.objects(es_mod.CALIBRATION_OMEGAS_PI, es_mod.CALIBRATION_ALPHAS_DEG)
    return [s for o in objs for s in es_mod.sweep_specs(o, es_mod.SWEEP_F_HZ, a_p_deg)]


def tilelink_sweeps(a_p_deg: float, cache: str | Path | None, executor=None, progress: bool = False,
                    backend: BackendSpec = TILELINK) -> list[list]:
    """The calibration objects' sweeps (lists of ProbeResult, one per object) at ``a_p_deg`` on ``backend``,
    simulating only the probes not in ``cache``."""
    from plate_env.run.sweeps import run_cached

    res = run_cached(backend, tilelink_specs(a_p_deg), cache, progress=progress, desc=f"A_p={a_p_deg:g}",
                     executor=executor)
    n = len(es_mod.SWEEP_F_HZ)
    return [res[i * n:(i + 1) * n] for i in range(len(res) // n)]


def sweep_line(sweeps: list[list], a_p_deg: float, dt_s: float | None, physics: str = TILELINK.name,
               model: str = TILELINK.option("model"), objects: list | None = None,
               objects_provenance: dict | None = None) -> Calibration | None:
    """The Eq. (10) line (and friction model) of the calibration objects' sweeps (lists of ProbeResult, object-major
    as :func:`tilelink_specs`; or of ``objects``, one sweep each, described in the provenance by
    ``objects_provenance``) at ``a_p_deg`` with the default fit rule (first hump), labelled ``physics/model``;
    None when fewer than 3 sweeps can be fitted."""
    from plate_env.identify.fitting import DEFAULT_DROP, DEFAULT_FLOOR, fit_results

    objs = objects if objects is not None else es_mod.objects(es_mod.CALIBRATION_OMEGAS_PI,
                                                              es_mod.CALIBRATION_ALPHAS_DEG)
    described = objects_provenance if objects is not None else {
        "objects_omega_n_pi": es_mod.CALIBRATION_OMEGAS_PI, "objects_alpha_deg": es_mod.CALIBRATION_ALPHAS_DEG}
    fits = [fit_results(sw) for sw in sweeps]
    good = [(f, o) for f, o in zip(fits, objs, strict=True) if f.ok]
    if len(good) < 3:
        return None
    return fit_calibration([f.f0 for f, _ in good], [o.omega_n for _, o in good], physics, model, a_p_deg,
                           omega_max_deg_s=[f.omega_max for f, _ in good], alpha_rad=[o.alpha for _, o in good],
                           provenance={**described, "f_p_hz": "10:40:1", "b_p_mm": 3.0, "window": "first_hump",
                                       "drop": DEFAULT_DROP, "floor": DEFAULT_FLOOR, "dt_s": dt_s,
                                       "sweeps_fitted": len(good), "sweeps_total": len(fits),
                                       "build": BUILD_COMMAND})


def _rigid_fast_grid():
    from plate_env.build.atlas import resolve_grid

    grid = resolve_grid(RIGID_FAST_GRID)
    lo, hi = min(es_mod.CALIBRATION_OMEGAS_PI), max(es_mod.CALIBRATION_OMEGAS_PI)
    nodes = (tuple(range(len(grid.f_hz))), (grid.a_p_deg.index(RIGID_FAST_AMP_DEG),),
             tuple(i for i, w in enumerate(grid.omega_n_pi) if lo <= w <= hi), tuple(range(len(grid.alpha_deg))))
    return grid, nodes


def rigid_fast_specs() -> list:
    """The faithful atlas's probes the rigid_fast line reads, placed as in the atlas's build."""
    from plate_env.build.atlas_grid import grid_probes

    grid, nodes = _rigid_fast_grid()
    order, specs = grid_probes(grid, RIGID_FAST_REPEATS, np.random.default_rng(RIGID_FAST_SEED))
    return [s for ix, s in zip(order, specs, strict=True) if all(i in n for i, n in zip(ix, nodes, strict=False))]


def missing_rigid_fast_probes(sweeps_dir: str | Path) -> int:
    """How many of the rigid_fast line's probes its cache in ``sweeps_dir`` lacks (0: read without simulating)."""
    from plate_env.run.sweeps import backend_tag, load_cache, spec_key

    path = Path(sweeps_dir) / RIGID_FAST_CACHE
    done = load_cache(path) if path.is_file() else {}
    tag = backend_tag(RIGID_FAST)
    return sum(spec_key(tag, s) not in done for s in rigid_fast_specs())


def rigid_fast_line(sweeps_dir: str | Path, dt_s: float | None) -> Calibration | None:
    """The faithful physics' Eq. (10) line at 3 deg from the faithful atlas's sweeps in ``sweeps_dir`` (complete:
    :func:`missing_rigid_fast_probes` is 0, else probes would be simulated), one sweep per (omega_n, alpha,
    repeat) node, fitted as :func:`sweep_line` fits the calibration objects'; None when fewer than 3 fit."""
    from plate_env.build.atlas_grid import run_grid

    grid, nodes = _rigid_fast_grid()
    res = run_grid(RIGID_FAST, grid, RIGID_FAST_REPEATS, RIGID_FAST_SEED, Path(sweeps_dir) / RIGID_FAST_CACHE,
                   progress=False, nodes=nodes)
    objs, sweeps = [], []
    for j, i_w in enumerate(nodes[2]):
        for k, i_al in enumerate(nodes[3]):
            for r in range(RIGID_FAST_REPEATS):
                objs.append(ObjectSpec.from_paper(grid.omega_n_pi[i_w], grid.alpha_deg[i_al]))
                sweeps.append(list(res[:, 0, j, k, r]))
    ws = [grid.omega_n_pi[i] for i in nodes[2]]
    return sweep_line(sweeps, RIGID_FAST_AMP_DEG, dt_s, RIGID_FAST.name, RIGID_FAST.option("model"), objs,
                      {"objects_omega_n_pi": ws, "objects_alpha_deg": list(grid.alpha_deg),
                       "sweeps": f"{RIGID_FAST_CACHE}: the faithful atlas's probes (grid {RIGID_FAST_GRID}, seed "
                                 f"{RIGID_FAST_SEED}, {RIGID_FAST_REPEATS} repeats, each probe placed on its own) at "
                                 f"{RIGID_FAST_AMP_DEG:g} deg, omega_n nodes {ws[0]}-{ws[-1]} pi (the calibration "
                                 "objects' range), every alpha node, one sweep per node and repeat"})


def lab_data(family: str, sweeps_dir: str | Path, executor=None, progress: bool = False) -> tuple[list[float], list]:
    """``(true omega_n rad/s per object, ProbeTable per object)`` of a lab family's set, from its cache in
    ``sweeps_dir`` (probes missing there are simulated and appended)."""
    es = LAB_SETS[family]
    tables = es_mod.run_eval_set(es, lab_backend_of(family), executor, progress, cache_dir=sweeps_dir)[es.a_p_deg[0]]
    return [o.omega_n for o in es.objects()], tables


def missing_lab_probes(family: str, sweeps_dir: str | Path) -> int:
    """How many of a lab family's probes its cache in ``sweeps_dir`` lacks (0: it can be read without simulating)."""
    from plate_env.run.sweeps import backend_tag, load_cache, spec_key

    es = LAB_SETS[family]
    path = Path(es.cache(es.a_p_deg[0], sweeps_dir))
    done = load_cache(path) if path.is_file() else {}
    nuis = es.nuisances() or [None] * es.n
    m, specs, backend_of = len(es.f_hz), es.specs(es.a_p_deg[0]), lab_backend_of(family)
    return sum(spec_key(backend_tag(backend_of(nuis[i // m])), s) not in done for i, s in enumerate(specs))


def lab_fits(data: dict[str, tuple[list[float], list]]) -> dict[str, list]:
    """Each family's ``[(true omega_n rad/s, LorentzFit)]`` from :func:`lab_data`'s ``{family: (truth, tables)}``."""
    from plate_env.identify.fitting import fit_lorentzian

    return {fam: [(w, fit_lorentzian(t.f_p_hz, t.omega_b_deg_s, t.stderr_deg_s, t.unstable))
                  for w, t in zip(*d, strict=True)] for fam, d in data.items()}


def lab_line(fits: dict[str, list], families: Sequence[str], physics: str = "lab",
             model: str = "lab") -> Calibration:
    """The Eq. (10) line of ``families``' fitted sweeps pooled at 3 deg, each family's own line kept: a model never
    seen is offset from it by the models' spread (Student-t, one degree of freedom fewer than the models with a
    line of their own)."""
    pts = [(fit.f0, w, fam) for fam in families for w, fit in fits[fam] if fit.ok]
    f0, w, groups = zip(*pts, strict=True)
    return fit_calibration(np.array(f0), np.array(w), physics, model, LAB_AMP_DEG, groups=list(groups),
                           provenance={"sweeps": {fam: LAB_SETS[fam].source for fam in families},
                                       "a_p_deg": LAB_AMP_DEG, "window": "first_hump", "build": BUILD_COMMAND})


def build_eq10(out: str | Path, record: dict, sweeps_dir: str | Path, lab_sweeps: str | Path,
               executor=None, progress: bool = True) -> list[Calibration]:
    """Write the four lines to ``out`` and the build record to ``out`` + ``.provenance.json``; returns them.

    The point-mass tile-link sweeps and the point-mass lab set are read from (and simulated into) ``sweeps_dir``;
    the rigid_fast sweeps and the other lab families are read from ``lab_sweeps``, checked complete before any
    probe runs (ValueError naming the file and how many probes it lacks)."""
    from plate_env.build.provenance import machine

    out, sweeps_dir, lab_sweeps = Path(out), Path(sweeps_dir), Path(lab_sweeps)
    if out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a directory: give the file to write")
    if not lab_sweeps.is_dir():
        raise ValueError(f"--lab-sweeps {str(lab_sweeps)!r} is not a directory (a checkout's experiments/cache holds "
                         "the rigid-limit and PyBullet sweeps of the lab line)")
    for fam in LAB_SETS:
        if fam not in LAB_SIMULATED and (n := missing_lab_probes(fam, lab_sweeps)):
            es = LAB_SETS[fam]
            raise ValueError(f"--lab-sweeps {str(lab_sweeps)!r}: {es.cache(es.a_p_deg[0], lab_sweeps)} lacks {n} "
                             f"of the {fam} family's {es.n * len(es.f_hz)} probes; the builder does not simulate "
                             "them (a checkout's experiments/cache holds them)")
    if n := missing_rigid_fast_probes(lab_sweeps):
        raise ValueError(f"--lab-sweeps {str(lab_sweeps)!r}: {lab_sweeps / RIGID_FAST_CACHE} lacks {n} of the "
                         f"rigid_fast line's {len(rigid_fast_specs())} probes (the faithful atlas's); the builder "
                         "does not simulate them (a checkout's experiments/cache holds them)")
    sweeps_dir.mkdir(parents=True, exist_ok=True)
    physics = TILELINK.build()
    dt = physics.dt
    physics.close()
    cals = []
    for amp in TILELINK_AMPS_DEG:
        cal = sweep_line(tilelink_sweeps(amp, sweeps_dir / TILELINK_CACHE, executor, progress), amp, dt)
        if cal is None:
            raise ValueError(f"fewer than 3 tile-link sweeps at {amp:g} deg can be fitted: no line")
        cals.append(cal)
    physics = RIGID_FAST.build()
    dt_rigid = physics.dt
    physics.close()
    rigid = rigid_fast_line(lab_sweeps, dt_rigid)
    if rigid is None:
        raise ValueError(f"fewer than 3 rigid_fast sweeps at {RIGID_FAST_AMP_DEG:g} deg can be fitted: no line")
    cals.append(rigid)
    # one run of probes per point-mass object (its own joint/contact draw): no progress bar for these
    data = {fam: lab_data(fam, sweeps_dir if fam in LAB_SIMULATED else lab_sweeps, executor) for fam in LAB_SETS}
    cals.append(lab_line(lab_fits(data), list(LAB_SETS)))
    save_calibrations(cals, out)
    record = {**record, "artifact": "calibration eq10", "machine": machine(),
              "inputs": {"simulated": {"tilelink": str(sweeps_dir / TILELINK_CACHE),
                                       **{f: LAB_SETS[f].cache(LAB_AMP_DEG, sweeps_dir) for f in LAB_SIMULATED}},
                         "read": {**{f: LAB_SETS[f].cache(LAB_AMP_DEG, lab_sweeps) for f in LAB_SETS
                                     if f not in LAB_SIMULATED},
                                  "rigid_fast": str(lab_sweeps / RIGID_FAST_CACHE)}},
              "lines": {f"{c.physics}/{c.model}/{c.a_p_deg:g}": {"n": c.n, "p1_pi": c.p1 / math.pi,
                                                                  "q1_pi": c.q1 / math.pi} for c in cals}}
    write_text_atomic(f"{out}.provenance.json", json.dumps(record, indent=1) + "\n", "build record")
    return cals


__all__: Sequence[str] = (
    "BUILD_COMMAND", "LAB_AMP_DEG", "LAB_SETS", "LAB_SIMULATED", "RIGID_FAST", "RIGID_FAST_AMP_DEG", "RIGID_FAST_CACHE",
    "RIGID_FAST_GRID", "RIGID_FAST_REPEATS", "RIGID_FAST_SEED", "TILELINK", "TILELINK_AMPS_DEG", "TILELINK_CACHE",
    "build_eq10", "lab_backend_of", "lab_data", "lab_fits", "lab_line", "missing_lab_probes",
    "missing_rigid_fast_probes", "rigid_fast_line", "rigid_fast_specs", "sweep_line", "tilelink_specs",
    "tilelink_sweeps")
