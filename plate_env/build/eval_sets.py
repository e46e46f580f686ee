"""Object sets and probe grids shared by the experiment scripts (calibration, atlas, evaluation, comparisons).

Calibration and atlas grid objects never coincide with the held-out objects used to score identification.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectPrior, ObjectSpec
from plate_env.core.probe import ProbeSpec
from plate_env.core.setup import PAPER_SETUP

#: Objects the Eq. (10) calibration is fitted on (omega_n in pi rad/s, alpha in degrees).
CALIBRATION_OMEGAS_PI = (3.5, 5.0, 7.0, 10.0, 13.0, 17.0, 23.0, 28.0, 33.0)
CALIBRATION_ALPHAS_DEG = (30.0, 36.9, 45.0, 56.3)
#: Held-out objects: omega_n and alpha values used by no calibration and no atlas grid point.
HELD_OUT_OMEGAS_PI = (4.2, 6.0, 8.5, 11.5, 15.0, 20.0, 25.5, 30.5)
HELD_OUT_ALPHAS_DEG = (33.0, 41.0, 50.0)
#: The atlas grid.
ATLAS_F_HZ = tuple(float(f) for f in np.arange(10.0, 40.01, 1.0))
ATLAS_AMPS_DEG = (3.0, 12.0)
ATLAS_OMEGAS_PI = tuple(float(w) for w in np.round(np.geomspace(1.4, 40.0, 16), 3))
ATLAS_ALPHAS_DEG = (28.0, 36.0, 44.0, 52.0, 60.0)
#: The paper's sweep: 10-40 Hz.
SWEEP_F_HZ = tuple(float(f) for f in np.arange(10.0, 40.01, 1.0))


def objects(omegas_pi, alphas_deg) -> list[ObjectSpec]:
    """Every combination, in the paper's units."""
    return [ObjectSpec.from_paper(w, a) for w in omegas_pi for a in alphas_deg]


def sweep_specs(obj: ObjectSpec, freqs_hz, a_p_deg: float, b_p_mm: float = PAPER_SETUP.b_p_mm, **kw) -> list[ProbeSpec]:
    """A frequency sweep of one object at one plate amplitude."""
    return [ProbeSpec(obj, PlateMotion.from_paper(float(f), a_p_deg, b_p_mm), **kw) for f in freqs_hz]


# --------------------------------------------------------------------------- the PyBullet atlas (issue 5)
#: The pybullet atlas grid: only ~10-24 Hz at A_p = 3 deg is informative on the PyBullet sheet (softer than ~5pi
#: folds, above the rising edge most probes slip off; experiments/results/pybullet_notes.md). >= 4 points per
#: axis (the atlas interpolates with cubic splines).
PYBULLET_ATLAS_F_HZ = tuple(float(f) for f in np.arange(10.0, 26.01, 2.0))
PYBULLET_ATLAS_AMPS_DEG = (3.0,)
PYBULLET_ATLAS_OMEGAS_PI = (5.0, 7.0, 10.0, 12.0, 14.0, 17.0, 20.0, 24.0, 28.0, 33.0)
PYBULLET_ATLAS_ALPHAS_DEG = (30.0, 40.0, 50.0, 60.0)
#: Shorter probe windows for the pybullet atlas and its evaluation (s): the ramp stays 0.2 s.
PYBULLET_SETTLE_S = 0.3
PYBULLET_MEASURE_S = 0.6
#: Placements (ProbeSpec initial_yaw rad, initial_offset u, v m) and grid objects (omega_n pi, alpha deg)
#: whose sweeps measure the pybullet atlas's between-placement spread (1 repeat per grid point otherwise).
PYBULLET_PLACEMENT_POSES = ((0.4, 3e-4, -2e-4), (1.0, -2e-4, 3e-4))
PYBULLET_PLACEMENT_OBJECTS = ((10.0, 40.0), (20.0, 50.0))
#: Held-out pybullet objects (omega_n pi, alpha deg): no omega_n or alpha value on the pybullet atlas grid.
PYBULLET_HELD_OUT_OBJECTS = ((6.0, 41.0), (8.5, 50.0), (11.5, 33.0), (16.5, 55.0), (23.0, 45.0), (25.5, 36.0),
                             (30.5, 52.0))


# --------------------------------------------------------------------------- identification prior and eval sets
#: The identification prior is the env's object prior (:class:`plate_env.core.objects.ObjectPrior`): omega_n
#: log-uniform over this range (pi rad/s) and alpha uniform over this range (deg).
PRIOR_OMEGA_PI = ObjectPrior.omega_n_range_pi
PRIOR_ALPHA_DEG = ObjectPrior.alpha_range_deg


def prior_objects(n: int, rng: np.random.Generator, omega_range_pi: tuple[float, float] = PRIOR_OMEGA_PI,
                  alpha_range_deg: tuple[float, float] = PRIOR_ALPHA_DEG,
                  mass_g: float = PAPER_SETUP.mass_g) -> list[ObjectSpec]:
    """``n`` objects drawn from the identification prior (per object: log omega_n, then alpha): the draws of
    :meth:`ObjectPrior.draw`, computed in numpy (the omega_n and alpha differ from it by at most 1 ulp; kept so
    that evaluation sets drawn with it stay bit for bit)."""
    out = []
    for _ in range(n):
        w = float(np.exp(rng.uniform(np.log(omega_range_pi[0]), np.log(omega_range_pi[1]))))
        a = float(rng.uniform(*alpha_range_deg))
        out.append(ObjectSpec.from_paper(w, a, mass_g=mass_g))
    return out


def placed_sweeps(objs: list[ObjectSpec], freqs_hz, a_p_deg: float, rng: np.random.Generator,
                  b_p_mm: float = PAPER_SETUP.b_p_mm, **kw) -> list[ProbeSpec]:
    """Frequency sweeps of every object, each probe placed as a real experiment would (``ProbeSpec.perturbed``)."""
    return [s.perturbed(rng) for o in objs for s in sweep_specs(o, freqs_hz, a_p_deg, b_p_mm, **kw)]


@dataclass(frozen=True)
class EvalSet:
    """Sweeps of objects drawn from the identification prior, from one source, for scoring identification.

    Objects come from ``prior_objects(n, default_rng(seed))``, placements from ``default_rng(seed + 1)`` (the same
    draws at every amplitude), and, with ``nuisance``, each object's unknown joint and contact values from
    ``plate_env.physics.nuisance.PRIOR`` with ``default_rng(seed + 2)``. ``source`` names the backend for caches and
    reports (e.g. ``"tilelink_pointmass"``); ``omega_range_pi`` narrows the prior for a model that cannot make
    every object (the PyBullet sheet folds below ~5pi).
    """

    source: str
    n: int
    seed: int
    a_p_deg: tuple[float, ...] = (3.0,)
    f_hz: tuple[float, ...] = SWEEP_F_HZ
    settle_s: float = 0.5
    measure_s: float = 1.0
    nuisance: bool = False
    omega_range_pi: tuple[float, float] = PRIOR_OMEGA_PI

    def objects(self) -> list[ObjectSpec]:
        return prior_objects(self.n, np.random.default_rng(self.seed), self.omega_range_pi)

    def nuisances(self) -> list | None:
        """Each object's :class:`plate_env.physics.nuisance.Nuisance` (None without ``nuisance``)."""
        if not self.nuisance:
            return None
        from plate_env.physics.nuisance import PRIOR

        rng = np.random.default_rng(self.seed + 2)
        return [PRIOR.draw(rng) for _ in range(self.n)]

    def specs(self, a_p_deg: float) -> list[ProbeSpec]:
        """The placed sweeps at one amplitude, object-major."""
        return placed_sweeps(self.objects(), self.f_hz, a_p_deg, np.random.default_rng(self.seed + 1),
                             settle_s=self.settle_s, measure_s=self.measure_s)

    def cache(self, a_p_deg: float, root: str | Path) -> str:
        """The set's sweep cache at one amplitude, in directory ``root``."""
        tag = "evalnuis" if self.nuisance else "eval"
        return f"{Path(root).as_posix()}/{tag}_{self.source}_A{a_p_deg:g}_s{self.seed}.jsonl"


def run_eval_set(es: EvalSet, backend_of, executor=None, progress: bool = False,
                 *, cache_dir: str | Path) -> dict:
    """``{A_p: [ProbeTable per object]}`` for an :class:`EvalSet`, run resumably (its cache files in ``cache_dir``).

    ``backend_of(nuisance)`` gives the :class:`plate_env.run.executor.BackendSpec` for an object's nuisance draw (None
    for a set without nuisances); objects sharing a backend run as one batch."""
    from plate_env.core.probe_table import ProbeTable
    from plate_env.run.sweeps import run_cached

    nuis = es.nuisances() or [None] * es.n
    m = len(es.f_hz)
    out = {}
    for amp in es.a_p_deg:
        specs = es.specs(amp)
        tables: list = [None] * es.n
        groups: dict = {}
        for i, nu in enumerate(nuis):
            groups.setdefault(backend_of(nu), []).append(i)
        for backend, idx in groups.items():
            sub = [s for i in idx for s in specs[i * m:(i + 1) * m]]
            res = run_cached(backend, sub, es.cache(amp, cache_dir), chunk=m, progress=progress,
                             desc=f"{es.source} A_p={amp:g}", executor=executor)
            for j, i in enumerate(idx):
                tables[i] = ProbeTable.from_results(res[j * m:(j + 1) * m])
        out[amp] = tables
    return out
