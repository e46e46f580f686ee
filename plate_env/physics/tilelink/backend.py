"""The tile-link physics backend: builds per-probe arrays, runs the numba kernels, measures omega_B."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from plate_env.core.objects import ObjectSpec
from plate_env.core.probe import (
    SLIP_LIMIT_M,
    ProbeResult,
    ProbeSpec,
    Status,
    YawTrace,
    check_probes,
    check_step_counts,
)
from plate_env.physics.interface import PhysicsBackend, warn_above_stable_dt
from plate_env.physics.measure import measure_omega_b
from plate_env.physics.tilelink.contact import PAPER_CONTACT, ContactLaw
from plate_env.physics.tilelink.params import (
    DEFAULT_DT,
    DEFAULT_RECORD_INTERVAL_S,
    P_CIN,
    P_KB,
    P_KIN,
    P_NSTEPS,
    P_RECEVERY,
    allocate_outputs,
    common_vector,
)
from plate_env.physics.tilelink.pointmass import (
    PointMassConfig,
    build_params,
    grid_damping_blocks,
    grid_layout,
    implicit_damping_matrix,
)
from plate_env.physics.tilelink.rigid import MODEL_CONFIGS, RigidTileConfig

MODELS = ("pointmass", "rigid", "rigid_limit", "rigid_fast")
#: The models run by the rigid-tile kernel.
RIGID_MODELS = ("rigid", "rigid_limit", "rigid_fast")
#: Point-mass kernels: "v1" (dense damper, the numbers the shipped atlases were built with) and "v2" (the damper
#: in the symmetry basis, faster; its omega_B against v1's: experiments/results/bench_kernel.md).
KERNELS = ("v1", "v2")
#: Largest time step measured stable for each model, s, and where: point mass, no blow-up over the 1600-probe
#: stress map at <= 4e-4 s, 52 % ran away at 6e-4 s; rigid, every probe ran away at 4e-4 s; rigid_limit, the
#: coarsest step measured (its rows at half the stiffness already run away at 2e-4 s); rigid_fast, with one sweep a
#: step its rows ran away at 5e-5 s (experiments/results/rigid_fast.md).
STABLE_DT = {"pointmass": (4e-4, "experiments/results/stress_tilelink_pointmass.md"),
             "rigid": (2e-4, "experiments/results/bench_models.md, rigid: omega_B against dt"),
             "rigid_limit": (5e-5, "experiments/results/bench_models.md, rigid_limit: omega_B against dt"),
             "rigid_fast": (2.5e-5, "experiments/results/rigid_fast.md")}
#: Probes per kernel call when a progress bar is shown.
PROGRESS_CHUNK = 8


@lru_cache(maxsize=256)
def _pointmass_params(obj: ObjectSpec, config: PointMassConfig):
    # one BLAS thread: the modal analysis' eigensolve differs in the last bits with the BLAS thread count, which
    # the kernel grows to ~1e-10 of omega_B; with it a probe repeats bit for bit in any process (plate_env.run.executor)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return build_params(obj, config)


@lru_cache(maxsize=256)
def _blocks(obj: ObjectSpec, config: PointMassConfig, dt: float) -> np.ndarray:
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return grid_damping_blocks(_pointmass_params(obj, config), dt)


@lru_cache(maxsize=16)
def _grid(diameter: float):
    from plate_env.physics.tilelink.geometry import disc_geometry

    return grid_layout(disc_geometry(diameter))


@lru_cache(maxsize=256)
def _ainv(obj: ObjectSpec, config: PointMassConfig, dt: float) -> np.ndarray:
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return implicit_damping_matrix(_pointmass_params(obj, config), dt)


class TileLinkPhysics(PhysicsBackend):
    """The paper's tile-link model.

    Args:
        model: ``"pointmass"`` (the fast point-mass reduction, default), ``"rigid"`` (52 rigid tiles with the
            joints' held motions as stiff rows at 5000 rad/s), ``"rigid_limit"`` (the same tiles with the rows
            in their converged rigid limit, :data:`rigid.RIGID_LIMIT_CONFIG`, at dt = 2.5e-5 s: the paper's
            model) or ``"rigid_fast"`` (the same model by small steps of one sweep each,
            :data:`rigid.RIGID_FAST_CONFIG`; accuracy, speed: ``experiments/results/rigid_fast.md``).
            Their speeds and first-hump fits: ``experiments/results/bench_models.md``.
        dt: time step, s; None takes the model's default (:data:`params.DEFAULT_DT`; its error against
            smaller steps: ``experiments/results/bench_physics.md`` and ``bench_models.md``).
        slip_limit: centre displacement (m, plate frame) beyond which a probe is unstable (the paper: 10 mm).
        config: joint parameters the paper does not give (point mass); rigid_config: those of the rigid tiles.
        contact: the plate contact law's coefficients (default: the paper's).
        record_interval_s: simulated seconds between recorded yaw/centre samples (rounded to whole steps, at
            least one); omega_B interpolates the records at the plate periods' boundaries, so this is part of
            a result's provenance (and of the sweep cache key, :func:`plate_env.run.sweeps.backend_tag`).
        kernel: the point-mass kernel, one of :data:`KERNELS` ("v1" default: the numbers the shipped atlases were
            built with; "v2": faster, omega_B within each probe's standard error of v1's, other bits). Part of
            the sweep cache key when not "v1".
    """

    def __init__(self, model: str = "pointmass", dt: float | None = None, slip_limit: float = SLIP_LIMIT_M,
                 config: PointMassConfig | None = None, rigid_config: RigidTileConfig | None = None,
                 contact: ContactLaw = PAPER_CONTACT, record_interval_s: float = DEFAULT_RECORD_INTERVAL_S,
                 kernel: str = "v1") -> None:
        if model not in MODELS:
            raise ValueError(f"unknown tilelink model {model!r}; choose one of {MODELS}")
        if kernel not in KERNELS:
            raise ValueError(f"unknown point-mass kernel {kernel!r}; choose one of {KERNELS}")
        if dt is None:
            dt = DEFAULT_DT[model]
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and 0.0 < dt <= 0.01):
            raise ValueError(f"time step dt = {dt!r} s is outside the allowed range (0, 0.01]")
        if not (math.isfinite(slip_limit) and slip_limit > 0):
            raise ValueError(f"slip_limit = {slip_limit!r} m must be a positive distance")
        if not (isinstance(record_interval_s, (int, float)) and math.isfinite(record_interval_s)
                and 0.0 < record_interval_s <= 0.1):
            raise ValueError(f"record_interval_s = {record_interval_s!r} s is outside the allowed range (0, 0.1]")
        limit, source = STABLE_DT[model]
        warn_above_stable_dt(float(dt), limit, f"the {model} model", source)
        self._model = model
        self.kernel = kernel
        self.dt = float(dt)
        self.slip_limit = float(slip_limit)
        self.record_interval_s = float(record_interval_s)
        self.config = config or PointMassConfig()
        if rigid_config is None:
            rigid_config = MODEL_CONFIGS.get(model, RigidTileConfig())
        self.rigid_config = rigid_config
        if not isinstance(contact, ContactLaw):
            raise TypeError(f"contact must be a ContactLaw, got {type(contact).__name__}")
        self.contact = contact

    name = "tilelink"
    SETTINGS = ("model", "dt", "config", "rigid_config", "contact", "record_interval_s", "slip_limit", "kernel")

    @property
    def model(self) -> str:
        return self._model

    def __repr__(self) -> str:
        return f"TileLinkPhysics(model={self.model!r}, dt={self.dt:g})"

    # ------------------------------------------------------------------ arrays
    def _param_vector(self, spec: ProbeSpec) -> np.ndarray:
        params = _pointmass_params(spec.obj, self.config)
        prm = common_vector(spec, self.dt, self.slip_limit, params.node_mass, law=self.contact,
                            record_interval_s=self.record_interval_s)
        prm[P_KB] = params.k_bending
        prm[P_KIN] = params.k_inplane
        prm[P_CIN] = params.c_inplane
        return prm

    def run_arrays(self, probes: Sequence[ProbeSpec]) -> dict[str, np.ndarray]:
        """Run the kernel on a batch and return its raw arrays (parameters, traces, status, records)."""
        if self.model in RIGID_MODELS:
            from plate_env.physics.tilelink.rigid_kernels import run_rigid_arrays

            return run_rigid_arrays(probes, self.dt, self.slip_limit, config=self.rigid_config, law=self.contact,
                                    record_interval_s=self.record_interval_s)
        prm = np.stack([self._param_vector(s) for s in probes])
        geom = _pointmass_params(probes[0].obj, self.config).geom
        rest = np.stack([_pointmass_params(s.obj, self.config).geom.rest for s in probes])
        if self.kernel == "v2":
            blocks = np.stack([_blocks(s.obj, self.config, self.dt) for s in probes])
            spacing = np.array([_pointmass_params(s.obj, self.config).geom.spacing for s in probes])
            return run_v2_arrays(prm, blocks, rest, geom, _grid(probes[0].obj.diameter), spacing)
        ainv = np.stack([_ainv(s.obj, self.config, self.dt) for s in probes])
        return self.run_param_arrays(prm, ainv, rest, geom)

    @staticmethod
    def run_param_arrays(prm: np.ndarray, ainv: np.ndarray, rest: np.ndarray, geom) -> dict[str, np.ndarray]:
        """Run the point-mass kernel on prepared arrays (exposed for tests that inject bad states)."""
        from plate_env.physics.tilelink import kernels as kn

        out = allocate_outputs(prm)
        kernel = kn.pointmass_batch_serial if len(prm) == 1 else kn.pointmass_batch_parallel
        kn.load_first(kn.pointmass_probe, prm[0], ainv[0], rest[0], geom.links, geom.diagonals, geom.triplets,
                      geom.cells, out["yaw"][0], out["cu"][0], out["cv"][0])
        kernel(prm, ainv, rest, geom.links, geom.diagonals, geom.triplets, geom.cells, out["yaw"], out["cu"],
               out["cv"], out["status"], out["nrec"])
        return out

    # ------------------------------------------------------------------ probes
    def check(self, probes: Sequence[ProbeSpec]) -> None:
        """Refuse (ProbeRefused) a probe of more than MAX_PROBE_STEPS time steps, before any work."""
        check_step_counts(check_probes(probes), self.dt)

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        """Simulate the probes as one batch (in chunks when a progress bar is shown); all are checked first."""
        probes = check_probes(probes)
        self.check(probes)
        if not probes:
            return []
        chunk = PROGRESS_CHUNK if progress else len(probes)
        results: list[ProbeResult] = []
        bar = None
        if progress:
            from plate_env.core.progress import progress_bar

            bar = progress_bar(len(probes), "probes", "probe")
        try:
            for start in range(0, len(probes), chunk):
                part = probes[start:start + chunk]
                t0 = time.perf_counter()
                raw = self.run_arrays(part)
                wall = (time.perf_counter() - t0) / len(part)
                results.extend(result_from_arrays(s, raw, b, self.dt, wall) for b, s in enumerate(part))
                if bar is not None:
                    bar.update(len(part))
        finally:
            if bar is not None:
                bar.close()
        return results


def run_v2_arrays(prm: np.ndarray, blocks: np.ndarray, rest: np.ndarray, geom, grid, spacing: np.ndarray
                  ) -> dict[str, np.ndarray]:
    """Run the v2 point-mass kernel on prepared arrays: ``blocks`` (B, 4, K, K) damper blocks, ``grid`` the
    :class:`GridLayout` of ``geom``, ``spacing`` (B,) each probe's grid spacing, m."""
    from plate_env.physics.tilelink import kernels_v2 as k2

    out = allocate_outputs(prm)
    pair_rest = spacing[:, None] * np.array([1.0, 1.0, math.sqrt(2.0), math.sqrt(2.0)])
    kernel = k2.pointmass_batch_serial if len(prm) == 1 else k2.pointmass_batch_parallel
    if grid.quad.shape[0] != k2.QUAD:
        raise ValueError(f"the v2 kernel needs {k2.QUAD} mirror orbits of nodes, the geometry has "
                         f"{grid.quad.shape[0]}")
    kernel(prm, blocks, grid.slot, grid.quad, grid.masks, pair_rest, rest, geom.cells, out["yaw"], out["cu"],
           out["cv"], out["status"], out["nrec"])
    return out


def result_from_arrays(spec: ProbeSpec, raw: dict[str, np.ndarray], b: int, dt: float, wall: float = 0.0
                       ) -> ProbeResult:
    """The :class:`ProbeResult` of probe ``b`` of a tile-link kernel's raw arrays (``run_arrays`` or
    ``run_rigid_param_arrays`` output) run at time step ``dt`` (s): omega_B from the yaw trace by
    :func:`measure_omega_b`, status, simulated time; ``wall``: wall seconds charged to the probe."""
    rec_dt = raw["prm"][b, P_RECEVERY] * dt
    nrec = int(raw["nrec"][b])
    t = np.arange(nrec) * rec_dt
    yaw = raw["yaw"][b, :nrec]
    status = Status(int(raw["status"][b]))
    unstable = status != Status.OK
    t_end = nrec * rec_dt if unstable else None
    period = 1.0 / spec.motion.freq_hz
    if nrec >= 2:
        omega, se, used = measure_omega_b(t, yaw, spec.measure_start_s, period, spec.n_periods, t_end)
    else:
        omega, se, used = 0.0, 0.0, 0
    sim_s = (nrec - 1) * rec_dt if unstable else raw["prm"][b, P_NSTEPS] * dt
    trace = None
    if spec.record_trace:
        trace = YawTrace(t=t, yaw=yaw.copy(), centre_u=raw["cu"][b, :nrec].copy(),
                         centre_v=raw["cv"][b, :nrec].copy())
    return ProbeResult(spec=spec, omega_b_deg_s=math.degrees(omega), stderr_deg_s=math.degrees(se),
                       unstable=unstable, reason=status.reason, sim_s=float(max(sim_s, 0.0)),
                       wall_s=wall, periods_measured=used, trace=trace)
