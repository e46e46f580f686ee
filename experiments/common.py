"""The helpers that several experiment scripts share, in one module (and only here: no script imports another).

A script imports it as ``import common`` / ``from common import ...``: Python puts the directory of the script it runs
first on ``sys.path``, so no path set-up is needed. Everything here uses the public API of ``plate_env`` and
``plate_env_agents`` only. Each section names the scripts it serves and the script it came from.
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

import plate_env as pe
from plate_env.bench.scoring import Scores
from plate_env.build import eval_sets as bm
from plate_env.build.eq10 import LAB_SETS, lab_backend_of
from plate_env.build.eval_sets import EvalSet, run_eval_set
from plate_env.core.probe import ProbeResult, ProbeSpec
from plate_env.core.probe_table import ProbeTable
from plate_env.identify.fitting import fit_lorentzian, fit_results
from plate_env.identify.forward import ForwardModel, Member
from plate_env.run.executor import BackendSpec
from plate_env.run.sweeps import backend_tag, load_cache, result_from_record, spec_key

#: The experiments folder and the checkout holding it.
HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: Where the scripts keep their resumable probe caches (relative to the checkout, where the scripts run).
CACHE = "experiments/cache"


# ---- Comparing two result JSONs; from same_numbers.py
#: Fields that are wall-clock measurements (differ between runs by nature).
WALL = ("seconds_per_decision",)


def diffs(a, b, path: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = [] if set(a) == set(b) else [f"{path}: keys {sorted(set(a) ^ set(b))}"]
        return out + [d for k in sorted(set(a) & set(b)) if k not in WALL for d in diffs(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} against {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in diffs(x, y, f"{path}[{i}]")]
    return [] if a == b or (a != a and b != b) else [f"{path}: {a!r} != {b!r}"]


# ---- Source trees under test (bench_speed, bench_fit_startup, same_episodes, layer_crossings); from bench_speed.py
def attr(module: str, old_module: str, name: str):
    """``module.name``, or ``old_module.name`` in a tree before the layered layout (issue 24): the measurements run
    on earlier commits too (``--ref``), so the old path is tried by name only where the new one does not exist."""
    import importlib

    try:
        return getattr(importlib.import_module(module), name)
    except ImportError:
        return getattr(importlib.import_module(old_module), name)


#: A lab sweep at A_p = 3 deg inside every shipped forward model's atlas (10-26 Hz: the PyBullet atlas's band).
#: A tile-link point-mass sweep of the README's object (omega_n 17 pi rad/s, alpha 45 deg), rounded to 4 decimals:
#: ``plate-env sweep --physics tilelink --omega-n 17pi --alpha 45 --freqs 10:26:2 --csv sweep.csv``. Every shipped
#: forward model gives an estimate from it (the fit timed is the one a user waits for, not a rejection).
SWEEP_CSV = "f_p_hz,a_p_deg,omega_b_deg_s,stderr_deg_s,unstable\n" + "\n".join(
    f"{f},{a},{w},{s},{u}" for f, a, w, s, u in [
        (10, 3, 12.0143, 0.0067, 0), (12, 3, 70.3582, 0.0252, 0), (14, 3, 87.0871, 0.3142, 0),
        (16, 3, 113.6140, 1.3952, 0), (18, 3, 183.7253, 1.0915, 0), (20, 3, 0.0000, 0.0000, 1),
        (22, 3, 417.7760, 2.2727, 0), (24, 3, 510.5472, 3.0620, 0), (26, 3, 555.6221, 3.4492, 0)]) + "\n"


SWEEP_POINTS = "9 points at A_p = 3 deg, 10-26 Hz (tile-link point mass, 17 pi rad/s, 45 deg)"


def tree_path(ref: str | None, tmp: Path) -> Path:
    """The source tree under test: this checkout (None) or ``git archive ref`` unpacked under ``tmp``."""
    if ref is None:
        return ROOT
    sha = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", ref], capture_output=True, text=True,
                         check=True).stdout.strip()
    dest = Path(tempfile.gettempdir()) / f"plate_env_bench_ref_{sha}"
    if not (dest / "plate_env").is_dir():
        dest.mkdir(parents=True, exist_ok=True)
        arch = subprocess.run(["git", "-C", str(ROOT), "archive", sha], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(dest)], input=arch, check=True)
    return dest


def overlay(tree: Path, tmp: Path) -> Path:
    """A directory whose ``plate_env`` and ``plate_env_agents`` are the tree's (first on PYTHONPATH: it wins over
    the editable install)."""
    d = tmp / tree.name.replace("/", "_")
    d.mkdir(exist_ok=True)
    for name, src in (("plate_env", tree / "plate_env"), ("plate_env_agents", tree / "agents")):
        link = d / name
        if not link.exists():
            link.symlink_to(src)
    return d


# ---- The paper's published numbers (encoded once); from reproduce_paper.py
ALPHA_CHEESE = 36.9


#: Fig. 7 fits in the paper: (omega_n [pi rad/s], alpha [deg]) -> (f0 [Hz], b [Hz], omega_max [deg/s], R^2).
PAPER_FIG7 = {(10.0, 36.9): (25.1, 5.1, 598.7, 0.99), (33.0, 36.9): (28.2, 5.8, 746.9, 0.99),
              (10.0, 56.3): (24.6, 5.8, 520.9, 0.98)}


#: Table 1 of the paper: A_p [deg] -> [(omega_n [pi rad/s], f_n [Hz], omega_Brmax [deg/s], f_B [Hz])].
PAPER_TABLE1 = {3.0: [(3.5, 1.75, 491.5, 1.36), (10.0, 5.00, 614.9, 1.71), (23.0, 11.5, 722.8, 2.01),
                      (33.0, 16.5, 796.1, 2.21)],
                12.0: [(1.4, 0.70, 278.1, 0.77), (3.5, 1.75, 275.8, 0.77), (6.5, 3.25, 334.2, 0.93),
                       (10.0, 5.00, 382.4, 1.06)]}


#: Eq. (10) coefficients (p1 [rad/s per Hz], q1 [rad/s]) and regression R^2 of Figs. 9 and 10, per A_p [deg].
PAPER_EQ10 = {3.0: (5.30, -121.62), 12.0: (5.65, -64.51)}


PAPER_R2 = {3.0: {"omega_max": 0.93, "f0": 0.99}, 12.0: {"omega_max": 0.83, "f0": 0.96}}


#: Fig. 11: A_p -> (R^2, slope, intercept [pi rad/s]).
PAPER_FIG11 = {3.0: (0.99, 0.99, 0.25), 12.0: (0.96, 0.96, 0.24)}


#: Objects of Figs. 8-10 per amplitude (the paper's Table 1 objects) and the friction angles swept.
FIG8_OMEGAS_PI = {3.0: (3.5, 10.0, 23.0, 33.0), 12.0: (1.4, 3.5, 6.5, 10.0)}


FIG8_ALPHAS_DEG = (30.0, 36.9, 45.0, 56.3)


def linreg(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Slope, intercept and R^2 of the least-squares line y = slope x + intercept."""
    if len(x) < 3:
        return math.nan, math.nan, math.nan
    slope, icpt = np.polyfit(x, y, 1)
    ss = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum((y - slope * x - icpt) ** 2)) / ss if ss > 0 else math.nan
    return float(slope), float(icpt), r2


# ---- The validation table's sweeps, placements and caches; from validate_paper.py
# (validate_paper, kept_12deg, falling_side, pybullet_hump)
MODELS = ("pointmass", "rigid", "rigid_limit", "pybullet")


#: Seeded placements per sweep, per model (the rigid limit and PyBullet cost ~1 and ~16 wall s a probe).
PLACEMENTS = {"pointmass": 4, "rigid": 3, "rigid_limit": 2, "pybullet": 2}


ALPHAS = FIG8_ALPHAS_DEG


CHEESE = ALPHA_CHEESE


#: Section 5's check: objects stiffer than 12pi at 12 deg (the paper: they become unstable or fold).
SEC5_STIFF_PI = (14.0, 23.0, 33.0)


FIG3 = {"f_hz": 12.0, "a_p_deg": 12.0, "omega_pi": 10.0, "alpha_deg": 36.9, "omega_b_deg_s": 344.0}


FIG10_RANGE = {3.0: (23.0, 30.0), 12.0: (11.0, 14.0)}


def canonical_freqs(a_p_deg: float) -> tuple[float, ...]:
    """Every plate frequency (Hz) a sweep may use: 10-40 Hz at 3 deg, 8-30 Hz at 12 deg (the paper's humps sit at
    11-14 Hz; above ~24 Hz every tile-link probe slips, reproduce_paper's Fig. 5(a)), 1 Hz apart. Placements are
    drawn over this list, so a model that probes a subset sees the same placement at each frequency."""
    return tuple(np.arange(10.0, 40.01, 1.0)) if a_p_deg == 3.0 else tuple(np.arange(8.0, 30.01, 1.0))


def freqs(model: str, a_p_deg: float) -> tuple[float, ...]:
    """Plate frequencies (Hz) of one sweep: the canonical list, or a subset for the dear models (the rigid limit
    16-36 Hz / 8-18 Hz, ~3 wall s a probe on an idle core; PyBullet every 2 Hz over 12-34 Hz / 8-20 Hz, ~16 s)."""
    if model == "pybullet":
        return tuple(np.arange(12.0, 34.01, 2.0)) if a_p_deg == 3.0 else tuple(np.arange(8.0, 20.01, 2.0))
    if model == "rigid_limit":
        return tuple(np.arange(16.0, 36.01, 1.0)) if a_p_deg == 3.0 else tuple(np.arange(8.0, 18.01, 1.0))
    return canonical_freqs(a_p_deg)


def windows(model: str) -> dict:
    """Probe windows: the project's defaults (0.5 s + 1.0 s), PyBullet its atlas's shorter ones (0.3 s + 0.6 s)."""
    if model == "pybullet":
        return {"settle_s": bm.PYBULLET_SETTLE_S, "measure_s": bm.PYBULLET_MEASURE_S}
    return {}


def backend(model: str) -> BackendSpec:
    if model == "pybullet":
        return BackendSpec.of("pybullet", n_workers=1)
    return BackendSpec.of("tilelink", model=model)


@dataclass(frozen=True)
class Sweep:
    """One object's sweep at one amplitude; ``stage`` orders the simulation (1 first)."""

    omega_pi: float
    alpha_deg: float
    a_p_deg: float
    stage: int

    @property
    def obj(self) -> pe.ObjectSpec:
        return pe.ObjectSpec.from_paper(self.omega_pi, self.alpha_deg)

    def specs(self, model: str, placement: int, freqs_hz: tuple[float, ...] | None = None) -> list[ProbeSpec]:
        """The sweep at one seeded placement: each probe placed by ``ProbeSpec.perturbed`` from a generator seeded
        by (placement, object, amplitude), so every model sees the same placements. ``freqs_hz`` (a subset of
        :func:`canonical_freqs`) replaces the model's frequencies; a probe at a shared frequency is the same."""
        rng = np.random.default_rng([placement, round(self.omega_pi * 10), round(self.alpha_deg * 10),
                                     round(self.a_p_deg * 10)])
        every = bm.placed_sweeps([self.obj], canonical_freqs(self.a_p_deg), self.a_p_deg, rng, **windows(model))
        keep = set(freqs(model, self.a_p_deg) if freqs_hz is None else freqs_hz)
        if not keep <= set(canonical_freqs(self.a_p_deg)):
            raise ValueError(f"frequencies {sorted(keep - set(canonical_freqs(self.a_p_deg)))} Hz are not on the "
                             f"{self.a_p_deg:g} deg grid (whole Hz, {canonical_freqs(self.a_p_deg)[0]:g}-"
                             f"{canonical_freqs(self.a_p_deg)[-1]:g})")
        return [sp for sp in every if sp.motion.freq_hz in keep]


def plan(model: str) -> list[Sweep]:
    """Every sweep the table needs, in stage order: 1 Fig. 7 and the Fig. 3 object; 2 the rest of Table 1 and
    Section 5 at alpha 36.9 deg; 3 the other friction angles of Figs. 8-10 (Eq. 10, Figs. 9-10). PyBullet's stage 1
    leaves Fig. 7(b) and (c) (33pi; 10pi at 56.3 deg) to stage 2 (its probes cost ~16 s)."""
    late = 2 if model == "pybullet" else 1
    s: list[Sweep] = [Sweep(10.0, CHEESE, 12.0, 1), Sweep(10.0, CHEESE, 3.0, 1), Sweep(33.0, CHEESE, 3.0, late),
                      Sweep(10.0, 56.3, 3.0, late)]
    for a in (3.0, 12.0):
        for w in FIG8_OMEGAS_PI[a]:
            if not any(x.omega_pi == w and x.alpha_deg == CHEESE and x.a_p_deg == a for x in s):
                s.append(Sweep(w, CHEESE, a, 2))
    s += [Sweep(w, CHEESE, 12.0, 2) for w in SEC5_STIFF_PI]
    for a in (3.0, 12.0):
        for w in FIG8_OMEGAS_PI[a]:
            for al in ALPHAS:
                if not any(x.omega_pi == w and x.alpha_deg == al and x.a_p_deg == a for x in s):
                    s.append(Sweep(w, al, a, 3))
    return s


def cache_path(cache_dir: Path, model: str) -> Path:
    return cache_dir / f"validate_paper_{model}.jsonl"


def cached_sweeps(model: str, cache_dir: Path) -> dict[tuple[Sweep, int], list[ProbeResult]]:
    """The sweeps (sweep, placement) -> results found complete in the cache; nothing is simulated."""
    tag = backend_tag(backend(model))
    done = load_cache(cache_path(cache_dir, model))
    out = {}
    for sw in plan(model):
        for p in range(PLACEMENTS[model]):
            specs = sw.specs(model, p)
            recs = [done.get(spec_key(tag, s)) for s in specs]
            if all(r is not None for r in recs):
                out[(sw, p)] = [result_from_record(s, r) for s, r in zip(specs, recs, strict=True)]
    return out


def observed(fit, f_hz) -> bool:
    """A fit the table uses: ok, and f0 inside the frequencies of the probes it used, widened by half their
    spacing (a Lorentzian whose top lies further out extrapolates a hump it never saw; such fits count as no
    estimate)."""
    if not fit.ok:
        return False
    f = np.unique(np.asarray(f_hz, float)[fit.used])
    if not f.size:
        return False
    half = 0.5 * float(np.min(np.diff(f))) if f.size > 1 else 0.0
    return bool(f.min() - half <= fit.f0 <= f.max() + half)


def fit_sweep(results: list[ProbeResult]):
    """The first-hump fit of a sweep, with ``ok`` False (reason given) when its f0 was not observed."""
    from dataclasses import replace

    fit = fit_results(results)
    if fit.ok and not observed(fit, [r.spec.motion.freq_hz for r in results]):
        return replace(fit, ok=False, reason=f"f0 {fit.f0:.1f} Hz outside the fitted probes")
    return fit


def git_commit(dirty: bool = True, under: str | None = None) -> str:
    """The checkout's short commit; with ``dirty``, ``+dirty`` when tracked files (only those under ``under``, a
    folder of the checkout such as ``"plate_env"``: which kernel a route ran on) have uncommitted changes;
    ``"unknown"`` outside git."""
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True,
                             cwd=ROOT)
        where = ["--", str(ROOT / under)] if under else []
        changed = dirty and subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", *where],
                                           capture_output=True, text=True, check=True, cwd=ROOT).stdout.strip()
        return out.stdout.strip() + ("+dirty" if changed else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


# ---- Slipped probes read as stable (kept_12deg, pybullet_hump); from kept_12deg.py
def kept(results: list) -> list:
    """``results`` with each slipped probe that measured at least one period read as stable."""
    return [replace(r, unstable=False, reason=None) if r.unstable and r.reason == "slipped" and r.periods_measured > 0
            else r for r in results]


# ---- Forward-model evaluation sets; from forward_models.py
# (forward_models, faithful_forward, calibration_study, npe_sbi, predictive_check)
POINTMASS = BackendSpec.of("tilelink", model="pointmass")


#: Calibration and test sets inside the point-mass model (10-40 Hz, 1 Hz, at 3 and 12 deg).
CALIBRATION = EvalSet("tilelink_pointmass", 120, 300, (3.0, 12.0))


TEST = EvalSet("tilelink_pointmass", 120, 200, (3.0, 12.0))


#: A second test set of the same size: coverage of 120 objects moves +-0.04 (68 %) and +-0.02 (95 %) by sampling.
TEST_MORE = EvalSet("tilelink_pointmass", 120, 210, (3.0, 12.0))


def sets_by_amplitude(data: dict, es: EvalSet) -> dict[str, list[ProbeTable]]:
    """The sweeps per object at each amplitude and at all amplitudes together ("3", "12", "3+12")."""
    out = {f"{a:g}": data[a] for a in es.a_p_deg}
    if len(es.a_p_deg) > 1:
        out["+".join(f"{a:g}" for a in es.a_p_deg)] = [ProbeTable.concat(*ts)
                                                       for ts in zip(*(data[a] for a in es.a_p_deg), strict=True)]
    return out


def row(label: str, s: Scores) -> str:
    return (f"| {label} | {s.n} | {s.median_error.fmt(100, 1, ' %')} | {s.p90_error.fmt(100, 1, ' %')} | "
            f"{s.coverage68.fmt(1, 2)} | {s.coverage95.fmt(1, 2)} | {s.width95.fmt(100, 0, ' %')} | "
            f"{s.no_estimate.fmt(1, 2)} |")


HEAD = ["| data, forward model | objects | median error | p90 error | 68 % coverage | 95 % coverage | "
        "median 95 % width / omega_n | no estimate |", "|---|---|---|---|---|---|---|---|"]


def episodes(args, fm: ForwardModel, seed: int) -> list[dict]:
    """``args.episodes`` bayes episodes on live tilelink, objects from the prior with ``seed`` (resumable: finished
    episodes, with their probes, are kept in experiments/cache)."""
    import gymnasium as gym

    from plate_env.build import eval_sets as bm
    from plate_env.env.episode import run_episode
    from plate_env.run.sweeps import open_for_append, read_records
    from plate_env_agents import make_agent

    cache = Path(f"experiments/cache/forward_models_bayes_s{seed}.jsonl")
    done = {d["i"]: d for d in read_records(cache) if "i" in d}
    objs = bm.prior_objects(args.episodes, np.random.default_rng(seed))
    if all(i in done for i in range(len(objs))):
        return [done[i] for i in range(len(objs))]
    env = gym.make("PlateRotation-v0", physics="tilelink", max_probes=30)
    with open_for_append(cache) as fh:
        for i, o in enumerate(objs):
            if i in done:
                continue
            t0 = time.perf_counter()
            res = run_episode(env, make_agent("bayes", forward=fm), seed=1000 + i,
                              options={"omega_n": o.omega_n, "alpha": o.alpha, "mass": o.mass})
            d = {"i": i, "omega_n": o.omega_n, "probes": res.n_probes, "sim_s": res.sim_s,
                 "wall_s": time.perf_counter() - t0, "estimate": res.estimate.to_dict(),
                 "table": res.probes.to_rows()}
            fh.write((json.dumps(d) + "\n").encode())
            fh.flush()
            done[i] = d
            print(f"episode {i}: {o.omega_n / math.pi:.1f}pi -> {d['estimate']['omega_n_pi']:.2f}pi "
                  f"({res.n_probes} probes)", file=sys.stderr, flush=True)
    env.close()
    return [done[i] for i in range(len(objs))]


def member(name: str) -> Member:
    """A shipped atlas as a member with its held-out model error (provenance). No blur: full sweeps are calibrated
    without it (the within stage); the bayes agent adds its own design blur (agents/bayes.py DESIGN_BLUR)."""
    from plate_env.surrogate.atlas import load_atlas_file

    atlas = load_atlas_file(name)
    return Member(atlas, float(atlas.provenance["sigma_model_deg_s"]))


#: Data of each family: point-mass objects each with its own draw of the unknown joint/contact values, the
#: paper-faithful rigid tiles (rigid_limit), the PyBullet sheet (which folds below ~5pi: objects from 5pi-33pi):
#: the sets the shipped lab Eq. (10) line is pooled over (plate_env.build.eq10).
DATA = LAB_SETS


backend_of = lab_backend_of


def data_of(family: str, executor, es: EvalSet | None = None) -> tuple[list[float], list[ProbeTable]]:
    es = es or DATA[family]
    tables = run_eval_set(es, backend_of(family), executor, cache_dir=CACHE)[es.a_p_deg[0]]
    return [o.omega_n for o in es.objects()], tables


# ---- Real-time factor of a backend and the speed harness (bench_physics, rigid_fast_validation,
# rigid_modal_validation); from bench_physics.py and rigid_fast_validation.py
def rtf(physics, specs, repeats: int, clock: Callable[[], float] = time.perf_counter) -> tuple[float, int]:
    """Simulated seconds per ``clock`` second of ``physics.run(specs)`` (the median of ``repeats`` runs after a
    warm-up run that compiles or loads caches) and the unstable probes of the last run."""
    physics.run(specs)  # warm (compile / load cache)
    times = []
    for _ in range(repeats):
        t0 = clock()
        res = physics.run(specs)
        times.append(clock() - t0)
    sim = sum(r.sim_s for r in res)
    return sim / statistics.median(times), sum(r.unstable for r in res)


def speed_probes() -> tuple[list[ProbeSpec], list[ProbeSpec]]:
    """bench_physics' harness: the cheese at 20 Hz alone, and a batch of 32 objects 5pi-36pi at 18-21 Hz (A_p 3 deg)."""
    cheese = pe.preset("cheese")
    one = [ProbeSpec(cheese, pe.PlateMotion.from_paper(20.0, 3.0))]
    batch = [ProbeSpec(cheese.with_(omega_n=(5 + k) * math.pi), pe.PlateMotion.from_paper(18 + 0.1 * k, 3.0))
             for k in range(32)]
    return one, batch


def speed(physics, pointmass, repeats: int, clock: Callable[[], float] = time.perf_counter,
          batch: bool = True) -> dict:
    """Real-time factors on :func:`speed_probes` (:func:`rtf`), ``physics`` as ``"route"`` and the point mass measured
    in the same run, the 1-minute load, and whether the route holds issue 26's goals (>= 10x one probe, >= 25x the
    batch of 32). ``clock``: time.perf_counter (wall, the default) or time.process_time (this process's CPU time,
    summed over its threads: the kernel's own cost on a loaded shared machine); ``batch=False``: one probe only."""
    one, many = speed_probes()
    out: dict = {}
    for name, phys in (("route", physics), ("pointmass", pointmass)):
        out[name] = {"one_probe_rtf": rtf(phys, one, repeats, clock)[0]}
        if batch:
            r32, bad = rtf(phys, many, repeats, clock)
            out[name].update(batch32_rtf=r32, batch32_unstable=bad)
    out["load_avg_1min"] = os.getloadavg()[0]
    out["holds"] = {"one_probe": out["route"]["one_probe_rtf"] >= 10.0}
    if batch:
        out["holds"]["batch32"] = out["route"]["batch32_rtf"] >= 25.0
    return out


# ---- Machine state for timing records (ppo_timing, zoo_timing); from ppo_timing.py
def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def commit() -> str | None:
    out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=Path(__file__).parent)
    return out.stdout.strip() or None


# ---- The converged rigid-limit reference, its probes and the scores against it (rigid_fast_validation,
# rigid_modal_validation); from rigid_fast_validation.py
RIGID_REFERENCE = HERE / "results" / "rigid_reference.json"
#: What a route must reach against the reference: omega_B median / max |relative difference| where both are stable,
#: stability agreement, first-hump f0 difference (Hz).
TOL_MEDIAN, TOL_MAX, TOL_AGREE, TOL_F0 = 0.02, 0.05, 0.90, 0.3


def load_reference() -> list[dict]:
    return json.loads(RIGID_REFERENCE.read_text())["probes"]


def spec_of(row: dict) -> ProbeSpec:
    """The reference probe exactly as it was run (object, motion, windows, placement)."""
    obj = pe.ObjectSpec.from_paper(row["omega_n_pi"], row["alpha_deg"])
    mot = pe.PlateMotion.from_paper(row["f_p_hz"], row["a_p_deg"], row["b_p_mm"])
    return ProbeSpec(obj=obj, motion=mot, settle_s=row["settle_s"], measure_s=row["measure_s"],
                     initial_yaw=row["initial_yaw_rad"], initial_offset=tuple(row["initial_offset_m"]))


def fits(rows: list[dict], omegas: list[float], unstable: list[bool]) -> dict[str, dict]:
    """First-hump fit per object (omega_n, alpha): f0, b, omega_max or the reason it cannot fit."""
    out = {}
    for key in sorted({(r["omega_n_pi"], r["alpha_deg"]) for r in rows}):
        idx = [i for i, r in enumerate(rows) if (r["omega_n_pi"], r["alpha_deg"]) == key]
        if len(idx) < 4:
            continue
        res = fit_lorentzian([rows[i]["f_p_hz"] for i in idx], [omegas[i] for i in idx],
                             unstable=[unstable[i] for i in idx])
        name = f"{key[0]:g}pi_{key[1]:g}deg"
        out[name] = ({"f0_hz": res.f0, "b_hz": res.b, "omega_max_deg_s": res.omega_max, "n_used": res.n_used}
                     if res.ok else {"reason": res.reason})
    return out


def compare(rows: list[dict], results) -> dict:
    """omega_B differences where both are stable, stability agreement, fits of both, per-probe rows."""
    ref_w = [r["omega_b_deg_s"] for r in rows]
    ref_u = [r["unstable"] for r in rows]
    new_w = [r.omega_b_deg_s for r in results]
    new_u = [r.unstable for r in results]
    rel = [(n - w) / abs(w) for w, u, n, v in zip(ref_w, ref_u, new_w, new_u, strict=True)
           if not u and not v and abs(w) > 0]
    agree = float(np.mean([u == v for u, v in zip(ref_u, new_u, strict=True)]))
    ref_fit, new_fit = fits(rows, ref_w, ref_u), fits(rows, new_w, new_u)
    ref_ok = [k for k in ref_fit if "f0_hz" in ref_fit[k]]
    df0 = {k: new_fit[k]["f0_hz"] - ref_fit[k]["f0_hz"] for k in ref_ok if "f0_hz" in new_fit.get(k, {})}
    arel = np.abs(rel) if rel else np.array([math.nan])
    summary = {"n_probes": len(rows), "n_both_stable": len(rel), "median_abs_rel": float(np.median(arel)),
               "max_abs_rel": float(np.max(arel)), "stability_agreement": agree, "f0_diff_hz": df0,
               "max_abs_f0_diff_hz": max((abs(v) for v in df0.values()), default=math.nan),
               "n_fits_compared": len(df0), "n_fits_reference": len(ref_ok),
               "n_sweeps": len(ref_fit)}
    summary["holds"] = {
        "omega_b_median": summary["median_abs_rel"] <= TOL_MEDIAN, "omega_b_max": summary["max_abs_rel"] <= TOL_MAX,
        "stability_agreement": agree >= TOL_AGREE,
        "fits": len(df0) == len(ref_ok) > 0 and summary["max_abs_f0_diff_hz"] <= TOL_F0}
    probes = [{"key": r["key"], "ref": w, "ref_unstable": u, "new": n, "new_unstable": v, "new_reason": x.reason}
              for r, w, u, n, v, x in zip(rows, ref_w, ref_u, new_w, new_u, results, strict=True)]
    return {"summary": summary, "fits_reference": ref_fit, "fits_route": new_fit, "probes": probes}


# ---- A calibration study's labs, scores and the hump-feature line (calibration_study, calibration_adaptive); from
# calibration_study.py
#: Each source's physics family (its members are left out of the forward model when it is the lab). ``pmlab``: the
#: point mass with lab-level nuisance (calibration_study's ``LabEvalSet``), several labs.
SOURCE_FAMILY = {"pointmass": "pointmass", "rigid": "rigid", "pybullet": "pybullet", "pmlab": "pointmass"}


@dataclass(frozen=True)
class LabEvalSet(EvalSet):
    """A simulated lab (regime "lab-level nuisance"): point-mass objects that all share ONE draw of the unknown
    joint and contact values from ``plate_env.physics.nuisance.PRIOR`` (``default_rng(seed + 2)``), the references
    and the test discs alike; objects and placements as :class:`plate_env.build.eval_sets.EvalSet`."""

    def nuisances(self) -> list:
        from plate_env.physics.nuisance import PRIOR

        shared = PRIOR.draw(np.random.default_rng(self.seed + 2))
        return [shared] * self.n

    def cache(self, a_p_deg: float, root: str | Path = "experiments/cache") -> str:
        return f"{Path(root).as_posix()}/evallab_{self.source}_A{a_p_deg:g}_s{self.seed}.jsonl"


#: The lab-level-nuisance source: several simulated labs (seeded), each its own nuisance draw shared by its discs.
LAB_SEEDS = (500, 510, 520, 530, 540, 550, 560, 570)
LAB_N = 20


def lab_sets(n_labs: int = len(LAB_SEEDS), n: int = LAB_N) -> list[LabEvalSet]:
    return [LabEvalSet("tilelink_pointmass", n, s, (3.0,), nuisance=True) for s in LAB_SEEDS[:n_labs]]


def source_data(fam: str, n: int | None, executor) -> tuple[list[float], list]:
    es = DATA[fam] if n is None else replace(DATA[fam], n=n)
    return data_of(fam, executor, es)


@dataclass(frozen=True)
class Lab:
    """One lab's discs: true omega_n (rad/s), every member's reading of each sweep, and each sweep's hump features
    (rows ok, f0 Hz, b Hz, omega_Brmax deg/s, f0 stderr Hz; NaN where the Lorentzian fit failed)."""

    name: str
    truth: np.ndarray
    readings: list
    features: np.ndarray
    shape_readings: list | None = None


def features_of(tables) -> np.ndarray:
    """Each sweep's first-hump Lorentzian (Eq. 9): (ok, f0, b, omega_Brmax, f0 stderr), NaN where it fails."""
    from plate_env.identify.fitting import fit_lorentzian

    out = np.full((len(tables), 5), np.nan)
    for i, t in enumerate(tables):
        f = fit_lorentzian(t.f_p_hz, t.omega_b_deg_s, t.stderr_deg_s, t.unstable)
        out[i, 0] = float(f.ok)
        if f.ok:
            out[i, 1:] = (f.f0, f.b, f.omega_max, f.f0_stderr)
    return out


def per_object_scores(truth: np.ndarray, preds) -> dict[str, np.ndarray]:
    err = np.array([abs(p.omega_n - w) / w if p.ok else math.inf for p, w in zip(preds, truth, strict=True)])
    in68 = np.array([p.ok and p.ci68[0] <= w <= p.ci68[1] for p, w in zip(preds, truth, strict=True)], float)
    in95 = np.array([p.ok and p.ci95[0] <= w <= p.ci95[1] for p, w in zip(preds, truth, strict=True)], float)
    width = np.array([(p.ci95[1] - p.ci95[0]) / w if p.ok else math.inf for p, w in zip(preds, truth, strict=True)])
    return {"error": err, "in68": in68, "in95": in95, "width95": width}


STATS = {
    "median_error": ("error", lambda x: np.nanmedian(x, axis=-1)),
    "p90_error": ("error", lambda x: np.nanpercentile(x, 90, axis=-1)),
    "coverage68": ("in68", lambda x: np.nanmean(x, axis=-1)),
    "coverage95": ("in95", lambda x: np.nanmean(x, axis=-1)),
    "width95": ("width95", lambda x: np.nanmedian(x, axis=-1)),
}


def boot_indices(labs: np.ndarray, rng: np.random.Generator, n_boot: int) -> np.ndarray:
    """Two-stage bootstrap rows (n_boot, n): within each source, its labs drawn with replacement, then objects drawn
    with replacement inside each drawn lab (a source with one lab: objects alone). ``labs``: per object, a
    ``source/lab`` label; the source is the part before the slash."""
    src_of = np.array([lab.split("/")[0] for lab in labs])
    members = {lab: np.flatnonzero(labs == lab) for lab in dict.fromkeys(labs)}
    by_src = {s_: [lab for lab in members if lab.split("/")[0] == s_] for s_ in dict.fromkeys(src_of)}
    rows = []
    for _ in range(n_boot):
        parts = []
        for names in by_src.values():
            for lab in rng.choice(len(names), size=len(names), replace=True):
                obj = members[names[lab]]
                parts.append(rng.choice(obj, size=obj.size, replace=True))
        row = np.concatenate(parts)
        rows.append(np.resize(row, labs.size))  # equal-size labs keep the length; resize guards unequal ones
    return np.array(rows)


def summarize(blocks: list[dict[str, np.ndarray]], rng: np.random.Generator, n_boot: int = 1000,
              stats: dict | None = None) -> dict:
    """Statistics over every (object, draw) pair with 95 % bootstrap intervals (an object carries all its draws):
    labs resampled within each source, then objects within each lab (:func:`boot_indices`). ``blocks``: per source,
    arrays (n_objects, n_draws) with NaN where the object was a reference, and ``lab`` labels."""
    arrays = {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}
    n = arrays["error"].shape[0]
    idx = boot_indices(arrays["lab"], rng, n_boot)
    out = {"objects": int(n), "pairs": int(np.isfinite(arrays["in95"]).sum())}
    for name, (key, fn) in (STATS if stats is None else stats).items():
        v = arrays[key].astype(float)
        value = float(fn(v.reshape(1, -1))[0])
        boot = np.array([fn(v[i].reshape(1, -1))[0] for i in idx])
        out[name] = {"value": value, "ci95": [float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))]}
    return out


#: Candidate (b), the paper's way: log omega_n linear in the hump's features x = (1, f0 - 26 Hz, log(omega_Brmax /
#: 600 deg/s)), a lab's coefficients from its K references, shrunk toward a prior learned from other labs.
FEAT_SIGMAS = np.geomspace(0.02, 1.0, 24)


#: The prior sd of each coefficient is at least the pseudo-labs' spread plus these floors (intercept, per Hz, per
#: unit log peak): a lab's physics may differ from every lab the prior saw.
FEAT_FLOOR = np.array([0.5, 0.1, 1.0])


def feat_x(F: np.ndarray) -> np.ndarray:
    return np.c_[np.ones(len(F)), F[:, 1] - 26.0, np.log(F[:, 3] / 600.0)]


@dataclass(frozen=True)
class FeatPrior:
    m0: np.ndarray
    c0: np.ndarray
    sigma_median: float
    log_sd: float


def _lab_fits(pseudo: list[Lab]):
    """Each pseudo-lab with at least 5 fitted sweeps: ``(lab, x, y, beta)``, its features' design rows, log truths
    and least-squares feature line."""
    for lab in pseudo:
        ok = lab.features[:, 0] == 1
        if ok.sum() < 5:
            continue
        x, y = feat_x(lab.features[ok]), np.log(lab.truth[ok])
        beta, *_ = np.linalg.lstsq(x, y, rcond=None)
        yield lab, x, y, beta


def _lab_lines(pseudo: list[Lab]) -> tuple[list[np.ndarray], list[float]]:
    """Each pseudo-lab's least-squares feature line over its fitted sweeps (at least 5) and its residual sd."""
    fits = list(_lab_fits(pseudo))
    return [beta for *_, beta in fits], [float(np.sqrt(np.mean((y - x @ beta) ** 2))) for _, x, y, beta in fits]


def learn_feat_prior(pseudo: list[Lab], log_sd: float) -> tuple[FeatPrior, dict]:
    """Coefficients by least squares on each pseudo-lab (all its fitted sweeps); the prior mean is their mean, its
    covariance their spread plus (|mean| + floor)^2 on the diagonal; the scatter prior log-normal around the
    geometric mean of their residual sds."""
    betas, sds = _lab_lines(pseudo)
    B = np.array(betas)
    m0 = B.mean(0)
    spread = np.cov(B.T) if len(B) > 1 else np.zeros((3, 3))
    c0 = spread + np.diag((np.abs(m0) * np.array([0, 1, 1]) + FEAT_FLOOR) ** 2)
    med = float(np.exp(np.mean(np.log(sds))))
    return FeatPrior(m0, c0, med, log_sd), {"pseudo_labs": [lab.name for lab in pseudo], "m0": m0.tolist(),
                                             "sd0": np.sqrt(np.diag(c0)).tolist(), "median": med, "log_sd": log_sd}


def feat_fit(prior: FeatPrior, F: np.ndarray, y: np.ndarray):
    """Posterior on the scatter grid: per sigma, the Gaussian posterior of the coefficients and the evidence."""
    ok = F[:, 0] == 1
    x, y = feat_x(F[ok]), y[ok]
    lp = -0.5 * ((np.log(FEAT_SIGMAS) - math.log(prior.sigma_median)) / prior.log_sd) ** 2
    prec0 = np.linalg.inv(prior.c0)
    out = []
    for j, sg in enumerate(FEAT_SIGMAS):
        cov_y = sg ** 2 * np.eye(len(y)) + x @ prior.c0 @ x.T
        r = y - x @ prior.m0
        sign, logdet = np.linalg.slogdet(cov_y)
        lp[j] += -0.5 * (logdet + r @ np.linalg.solve(cov_y, r))
        cn = np.linalg.inv(prec0 + x.T @ x / sg ** 2)
        mn = cn @ (prec0 @ prior.m0 + x.T @ y / sg ** 2)
        out.append((mn, cn))
    wt = np.exp(lp - lp.max())
    return wt / wt.sum(), out


FEAT_Y = np.linspace(math.log(1.0), math.log(400.0), 2400)


def feat_predict(post, f_row: np.ndarray):
    from plate_env.identify.lab_calibration import Prediction

    if f_row[0] != 1:
        return Prediction(False, reason="no Lorentzian fit")
    wt, parts = post
    x = feat_x(f_row[None])[0]
    cdf = np.zeros_like(FEAT_Y)
    from scipy.stats import norm

    for w, sg, (mn, cn) in zip(wt, FEAT_SIGMAS, parts, strict=True):
        if w < 1e-8:
            continue
        cdf += w * norm.cdf(FEAT_Y, x @ mn, math.sqrt(sg ** 2 + x @ cn @ x))
    cdf /= cdf[-1]

    def q(level: float) -> float:
        return float(math.exp(np.interp(level, cdf, FEAT_Y)))

    return Prediction(True, q(0.5), (q(0.16), q(0.84)), (q(0.025), q(0.975)))


def cell(st: dict, scale: float = 100, digits: int = 0, unit: str = " %") -> str:
    v, (lo, hi) = st["value"], st["ci95"]
    return f"{v * scale:.{digits}f}{unit} [{lo * scale:.{digits}f}, {hi * scale:.{digits}f}]"


def prior_text(p: dict) -> str:
    if isinstance(p.get("pseudo_labs"), dict):
        return (f"scatter median {p['median']:.3f}, sd(log) {p['log_sd']:g} (from "
                + ", ".join(f"{k} {v:.3f}" for k, v in p["pseudo_labs"].items()) + ")")
    if "m0" in p:
        return (f"coefficients {', '.join(f'{x:.3g}' for x in p['m0'])} (sd {', '.join(f'{x:.3g}' for x in p['sd0'])}),"
                f" scatter median {p['median']:.3f}, sd(log) {p['log_sd']:g}, from {', '.join(p['pseudo_labs'])}")
    return str(p.get("pseudo_labs"))


# ---- The member-likelihood readings of a calibration study's labs, the readings map's scatter prior and each
# source's information limit (calibration_study, calibration_adaptive); from calibration_study.py
#: The physics families, in the order of the ``lab`` forward model's members (:func:`all_members`).
FAMILY_ORDER = ("pointmass", "rigid", "pybullet")


def member_files() -> list[str]:
    """The atlas file of every member of every family, in :data:`FAMILY_ORDER`."""
    from plate_env.build.forward_models import FAMILIES

    return [f for fam in FAMILY_ORDER for f in FAMILIES[fam]]


def all_members() -> tuple[ForwardModel, list[str]]:
    """Every member of every family (the ``lab`` forward model's members at 13.6 g) and each one's family."""
    from plate_env.build.forward_models import FAMILIES

    members, fams = [], []
    for fam in FAMILY_ORDER:
        for f in FAMILIES[fam]:
            members.append(member(f))
            fams.append(fam)
    return ForwardModel("all", tuple(members)), fams


def readings_of(name: str, tables, fm: ForwardModel, shape: bool = False, only=None) -> list:
    """Every member's reading of every sweep of a lab (:func:`plate_env.identify.lab_calibration.member_readings`;
    cached in ``experiments/cache/calibration_readings[_shape]_{name}_n{len}.npz``: they depend on the data and the
    atlases only); ``shape``: the shape-only reading (amplitude marginalised over ``SHAPE_SCALES``), of the members
    ``only``."""
    from plate_env.identify.lab_calibration import SHAPE_SCALES, Readings, member_readings

    path = Path(CACHE) / f"calibration_readings{'_shape' if shape else ''}_{name}_n{len(tables)}.npz"
    if path.exists():
        z = np.load(path)
        return [Readings(z["log_w"], p, lz) for p, lz in zip(z["prob"], z["log_z"], strict=True)]
    t0 = time.perf_counter()
    out = [member_readings(fm, t, amplitude_scales=SHAPE_SCALES if shape else None, only=only) for t in tables]
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, log_w=out[0].log_w, prob=np.stack([r.prob for r in out]),
                        log_z=np.stack([r.log_z for r in out]))
    print(f"readings {name}: {len(tables)} sweeps x {len(fm.members)} members in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr, flush=True)
    return out


def lab_readings(readings: list, fams: list[str], exclude: set[str], pooling: str = "member") -> tuple[list, list]:
    """The readings of the members outside the families ``exclude``: each member alone (``pooling="member"``) or
    each family's members pooled by evidence (``"family"``); and their names."""
    names = member_files()
    if pooling == "member":
        idx = [i for i, f in enumerate(fams) if f not in exclude]
        return [r.subset(idx) for r in readings], [names[i] for i in idx]
    groups = {f: [i for i, g in enumerate(fams) if g == f] for f in FAMILY_ORDER if f not in exclude}
    return [r.pooled(list(groups.values())) for r in readings], list(groups)


def learn_scatter_prior(src: str, data: dict, fams: list[str], log_sd: float, pooling: str = "member",
                        shape: bool = False):
    """The readings map's scatter prior for ``src`` (a ``ScatterPrior`` and a report) from the labs of other families
    read through members of neither the lab's nor their own family: each such pseudo-lab fitted with all its objects
    as references (a flat scatter prior), its posterior mean scatter with b = 1; the prior's median is their
    geometric mean, ``log_sd`` its spread. ``data``: source -> labs (:class:`Lab`)."""
    from plate_env.identify.lab_calibration import ScatterPrior, fit_lab

    flat = ScatterPrior(0.2, 5.0)
    found = {}
    for s, labs in data.items():
        if SOURCE_FAMILY[s] == SOURCE_FAMILY[src]:
            continue
        for lab in labs:
            refs, names = lab_readings(lab.shape_readings if shape else lab.readings, fams,
                                       {SOURCE_FAMILY[src], SOURCE_FAMILY[s]}, pooling)
            # the scatter left with b = 1: a prior learned with the slope made K = 1 over-confident (coverage 0.79)
            post = fit_lab(refs, np.log(lab.truth), names, flat, slope=False)
            found[lab.name] = post.summary()["sigma_mean"]
    med = float(np.exp(np.mean(np.log(list(found.values())))))
    return ScatterPrior(med, log_sd), {"pseudo_labs": found, "median": med, "log_sd": log_sd}


def width95_of_sd(sd: float) -> float:
    """The 95 % width (share of omega_n) of a normal scatter ``sd`` in log omega_n: e^(1.96 sd) - e^(-1.96 sd)."""
    return math.exp(1.96 * sd) - math.exp(-1.96 * sd)


#: The share of a source's discs a map must read for its in-sample scatter to be the source's information limit.
LIMIT_SHARE = 0.9


def information_limit(labs: list[Lab], fams: list[str], family: str) -> dict:
    """What the data of one source allow, in-sample (an oracle: every disc of each lab is a reference and is
    scored, no reference budget): per map, the residual scatter (sd of log omega_n, root mean square over the labs,
    weighted by their discs) and the median absolute error.

    ``features``: least squares of log omega_n on (1, f0, log omega_Brmax) per lab, over its discs with a Lorentzian
    fit (``n`` of ``of``); ``readings``: the member-likelihood map (member weights + offset, b = 1; the members of
    ``family`` left out) fitted to every disc of the lab with a flat scatter prior, its posterior mean scatter and
    the median error of its in-sample predictions. ``best``: the smaller scatter of the two maps that read at least
    :data:`LIMIT_SHARE` of the discs, and its 95 % width (:func:`width95_of_sd`), the narrowest calibrated 95 %
    interval these data could support."""
    from plate_env.identify.lab_calibration import ScatterPrior, fit_lab, predict

    out = {}
    ss, errs, n_ok, n_all = 0.0, [], 0, 0
    for lab in labs:
        ok = lab.features[:, 0] == 1
        n_all += int(ok.size)
        if ok.sum() < 4:
            continue
        x, y = feat_x(lab.features[ok]), np.log(lab.truth[ok])
        beta, *_ = np.linalg.lstsq(x, y, rcond=None)
        r = y - x @ beta
        ss += float(np.sum(r ** 2))
        n_ok += int(ok.sum())
        errs += list(np.abs(np.expm1(r)))
    if n_ok:
        out["features"] = {"sd": math.sqrt(ss / n_ok), "median_error": float(np.median(errs)), "n": n_ok,
                           "of": n_all}
    ss, errs, n = 0.0, [], 0
    for lab in labs:
        rd, names = lab_readings(lab.readings, fams, {family})
        post = fit_lab(rd, np.log(lab.truth), names, ScatterPrior(0.2, 5.0), slope=False)
        sg = post.summary()["sigma_mean"]
        ss += sg ** 2 * len(rd)
        n += len(rd)
        errs += [abs(p.omega_n / w - 1) if p.ok else math.inf
                 for p, w in zip((predict(post, r) for r in rd), lab.truth, strict=True)]
    out["readings"] = {"sd": math.sqrt(ss / n), "median_error": float(np.median(errs)), "n": n, "of": n}
    # a feature line that fits too few of the discs (the Lorentzian fails) is no limit for the source: the readings
    best = min(("features", "readings"), key=lambda k: out[k]["sd"] if k in out and out[k]["n"] >= LIMIT_SHARE *
               out[k]["of"] else math.inf)
    out["best"] = {"map": best, "sd": out[best]["sd"], "width95": width95_of_sd(out[best]["sd"])}
    return out


def limit_text(lim: dict) -> str:
    """An information limit in a table cell: the best map's scatter and 95 % width, and each map's scatter."""
    parts = [f"{k} {lim[k]['sd']:.3f}" for k in ("features", "readings") if k in lim]
    return f"{lim['best']['width95']:.0%} (sd {lim['best']['sd']:.3f}; " + ", ".join(parts) + ")"


# ---- The lab-adaptive feature line and scores with the discs without an estimate (calibration_adaptive,
# calibration_plans); from calibration_adaptive.py
def learn_feat_prior_wide(pseudo: list[Lab], log_sd: float) -> tuple[FeatPrior, dict]:
    """:func:`learn_feat_prior`, with the scatter prior's spread max(``log_sd``, the pseudo-labs' spread of log sd):
    a wide hierarchical prior over labs, so that the references' own residuals decide a lab's scatter."""
    prior, info = learn_feat_prior(pseudo, log_sd)
    _, sds = _lab_lines(pseudo)
    spread = float(np.std(np.log(sds))) if len(sds) > 1 else 0.0
    lsd = max(log_sd, spread)
    info["log_sd"] = lsd
    return FeatPrior(prior.m0, prior.c0, prior.sigma_median, lsd), info


#: Beside the study's statistics: the share of discs without an estimate and the coverage among the discs with one
#: (``coverage95`` counts a disc without an estimate as a miss).
STATS_MISS = {**STATS, "no_estimate": ("miss", lambda x: np.nanmean(x, axis=-1)),
              "coverage95_given": ("in95g", lambda x: np.nanmean(x, axis=-1)),
              "coverage68_given": ("in68g", lambda x: np.nanmean(x, axis=-1))}
SCORE_KEYS = ("error", "in68", "in95", "width95", "miss", "in95g", "in68g")


def scores_with_miss(truth: np.ndarray, preds) -> dict[str, np.ndarray]:
    """:func:`per_object_scores` plus ``miss`` (1: no estimate) and the coverages with NaN where there is no
    estimate."""
    out = per_object_scores(truth, preds)
    ok = np.array([p.ok for p in preds])
    out["miss"] = (~ok).astype(float)
    out["in95g"] = np.where(ok, out["in95"], np.nan)
    out["in68g"] = np.where(ok, out["in68"], np.nan)
    return out


def lab_family(name: str) -> str:
    """The physics family of a pseudo-lab by its name (``learn_feat_mixture(by="family")``)."""
    return "pointmass" if name.startswith(("pointmass", "pmlab")) else "rigid" if name.startswith("rigid") else name


def learn_feat_mixture(pseudo: list[Lab], log_sd: float, broad_weight: float = 0.5, offset_sd: float = 0.5,
                       slope_sd: tuple[float, float] = (0.05, 1.0), lab_log_sd: float = 0.75, by: str = "lab",
                       reduced: float = 0.0):
    """A mixture prior over labs for the feature line (``adaptive_calibration.FeatureMixture``): the broad prior of
    :func:`learn_feat_prior_wide` (weight ``broad_weight``) and one component per pseudo-lab with at least 5 fitted
    sweeps (the rest shared equally): its least-squares line, its coefficients' covariance plus a kernel
    (intercept ``offset_sd``: a lab's offset is re-learned; slopes ``slope_sd`` per Hz and per unit log peak), its
    residual sd the scatter's median (spread ``lab_log_sd``). ``by="family"``: one component per physics family
    (:func:`lab_family`) instead, its labs' components pooled (mean line; mean covariance plus the lines' spread;
    scatter median their geometric mean, spread the larger of ``lab_log_sd`` and theirs)."""
    from plate_env.identify.adaptive_calibration import FeatureMixture, FeaturePrior

    broad, info = learn_feat_prior_wide(pseudo, log_sd)
    comps = [FeaturePrior(tuple(float(v) for v in broad.m0), tuple(tuple(float(v) for v in r) for r in broad.c0),
                          float(broad.sigma_median), float(broad.log_sd))]
    labels = ["broad"]
    kern = np.diag([offset_sd ** 2, slope_sd[0] ** 2, slope_sd[1] ** 2])
    for lab, x, y, beta in _lab_fits(pseudo):
        sd = float(np.sqrt(np.sum((y - x @ beta) ** 2) / (len(y) - 3)))
        c = sd ** 2 * np.linalg.inv(x.T @ x) + kern
        c = 0.5 * (c + c.T)
        comps.append(FeaturePrior(tuple(float(v) for v in beta), tuple(tuple(float(v) for v in r) for r in c),
                                  min(sd, 2.0), lab_log_sd))
        labels.append(lab.name)
    if by == "family":  # one component per physics family: its labs' lines pooled (mean; spread + mean covariance)
        groups: dict[str, list[int]] = {}
        for i, name in enumerate(labels[1:], start=1):
            groups.setdefault(lab_family(name), []).append(i)
        fam_comps, fam_labels = [comps[0]], ["broad"]
        for fam, idx in groups.items():
            B = np.array([comps[i].mean for i in idx])
            C = np.mean([np.asarray(comps[i].cov) for i in idx], axis=0)
            C = C + (np.cov(B.T) if len(idx) > 1 else 0.0)
            lsd = np.log([comps[i].sigma_median for i in idx])
            fam_comps.append(FeaturePrior(tuple(float(v) for v in B.mean(0)),
                                          tuple(tuple(float(v) for v in r) for r in 0.5 * (C + C.T)),
                                          float(np.exp(lsd.mean())), float(max(lab_log_sd, lsd.std()))))
            fam_labels.append(fam)
        comps, labels = fam_comps, fam_labels
    n = len(comps) - 1
    weights = (1.0,) if n == 0 else (broad_weight, *([(1 - broad_weight) / n] * n))
    if reduced > 0:  # a broad line in log omega_Brmax alone (f0 slope pinned near 0): share ``reduced`` of the broad's
        rows = []
        for lab in pseudo:
            ok = lab.features[:, 0] == 1
            if ok.sum() < 5:
                continue
            x, y = feat_x(lab.features[ok])[:, [0, 2]], np.log(lab.truth[ok])
            beta, *_ = np.linalg.lstsq(x, y, rcond=None)
            rows.append((beta, float(np.sqrt(np.mean((y - x @ beta) ** 2)))))
        B = np.array([r[0] for r in rows])
        c2 = (np.cov(B.T) if len(B) > 1 else np.zeros((2, 2))) + np.diag([0.5 ** 2, 1.0 ** 2])
        c = np.array([[c2[0, 0], 0.0, c2[0, 1]], [0.0, 0.02 ** 2, 0.0], [c2[1, 0], 0.0, c2[1, 1]]])
        red = FeaturePrior((float(B[:, 0].mean()), 0.0, float(B[:, 1].mean())), tuple(tuple(float(v) for v in r)
                                                                                    for r in c),
                           float(np.exp(np.mean(np.log([r[1] for r in rows])))), float(broad.log_sd))
        comps.insert(1, red)
        labels.insert(1, "broad, log omega_Brmax only")
        weights = (weights[0] * (1 - reduced), weights[0] * reduced, *weights[1:])
    info = {**info, "mixture": {"by": by, "labels": labels, "weights": list(weights), "offset_sd": offset_sd,
                                "slope_sd": list(slope_sd), "lab_log_sd": lab_log_sd,
                                "lab_sigma": [c.sigma_median for c in comps[1:]]}}
    return FeatureMixture(tuple(comps), weights, tuple(labels)), info
