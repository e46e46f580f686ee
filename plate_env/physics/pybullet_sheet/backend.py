"""The PyBullet physics backend: probes grouped into object sequences, run serially or over a process pool."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor

from plate_env.core.probe import (
    NON_FINITE,
    SLIP_LIMIT_M,
    ProbeResult,
    ProbeSpec,
    check_probes,
    check_step_counts,
)
from plate_env.physics.interface import PhysicsBackend, warn_above_stable_dt
from plate_env.physics.pybullet_sheet.scene import Client, SheetConfig, SheetScene

#: Largest time step measured stable over the whole omega_n range, s (33pi runs away at 8e-4 s).
STABLE_DT = (4e-4, "experiments/results/pybullet_notes.md")

#: The worker process's client (one per process, opened by the first unit the worker runs).
_WORKER_CLIENT: Client | None = None


def _failed(spec: ProbeSpec, reason: str, wall: float) -> ProbeResult:
    return ProbeResult(spec=spec, omega_b_deg_s=0.0, stderr_deg_s=0.0, unstable=True, reason=reason, sim_s=0.0,
                       wall_s=wall, periods_measured=0)


def run_unit(client: Client, probes: Sequence[ProbeSpec], config: SheetConfig, stderr_tol_deg_s: float | None,
             k_elastic: float | None = None) -> list[ProbeResult]:
    """Run one unit: a fresh scene for the unit's object, placed at its first probe's ``initial_yaw`` and
    ``initial_offset``, then its probes in order (continuing the sheet's state).

    A probe that ends unstable leaves the next probe a freshly built scene (at that probe's placement). Never
    raises: an engine error becomes an unstable result with reason ``non_finite``.
    """
    from plate_env.physics.pybullet_sheet.calibrate import calibrated_k

    out: list[ProbeResult] = []
    scene: SheetScene | None = None
    for spec in probes:
        t0 = time.perf_counter()
        try:
            if scene is None or not scene.alive:
                k = k_elastic if k_elastic is not None else calibrated_k(spec.obj, config)[0]
                scene = SheetScene(client, spec.obj, k, config, initial_yaw=spec.initial_yaw,
                                   initial_offset=spec.initial_offset)
            out.append(scene.run_probe(spec, stderr_tol_deg_s))
        except Exception:  # noqa: BLE001 - a probe must never raise out of run()
            scene = None
            out.append(_failed(spec, NON_FINITE, time.perf_counter() - t0))
    return out


def _worker_unit(args: tuple) -> list[ProbeResult]:
    global _WORKER_CLIENT
    if _WORKER_CLIENT is None:
        _WORKER_CLIENT = Client()
    return run_unit(_WORKER_CLIENT, *args)


class PyBulletPhysics(PhysicsBackend):
    """A two-layer tetrahedral mass-spring sheet on a driven plate in PyBullet's deformable world.

    Probes are split into *units*: runs of consecutive probes with the same object and the same placement
    (``ProbeSpec.initial_yaw``, ``initial_offset``), at most ``sequence_len`` long. Each unit builds its scene once,
    with the sheet at that placement, and runs its probes like a real experiment (the plate restarts from rest with
    the next probe's ramp, the sheet keeps its state). A probe asking for another placement starts a new unit, so
    every placement asked for is honoured (the env's random placements, ``ProbeSpec.perturbed``). Units depend only
    on the probe list, so a pool of ``n_workers`` processes gives bit-identical results to the serial run.

    Args:
        dt: time step, s (4e-4 s default; omega_B against dt: ``experiments/results/pybullet_notes.md``).
        n_layer: mesh points per layer (the sheet has twice as many nodes); 91, the default, is the knee of
            omega_B against the mesh (``experiments/results/pybullet_notes.md``).
        thickness: sheet thickness (layer gap), m.
        n_workers: processes (1 = run in this process). Use at most one per core.
        sequence_len: probes per unit (1 = a fresh scene for every probe).
        stderr_tol_deg_s: stop a probe's measurement early once omega_B's standard error is below this (deg/s).
        slip_limit: plate-frame centre displacement that makes a probe unstable, m.
        config: a full :class:`SheetConfig` (overrides dt, n_layer, thickness, slip_limit).
        k_elastic: fixed spring stiffness, N/m, bypassing the omega_n calibration (tests, benchmarks).
    """

    name = "pybullet"
    SETTINGS = ("dt", "config", "k_elastic", "stderr_tol_deg_s")

    def __init__(self, dt: float = 4e-4, n_layer: int = 91, thickness: float = 0.002, n_workers: int = 1,
                 sequence_len: int = 8, stderr_tol_deg_s: float | None = None, slip_limit: float = SLIP_LIMIT_M,
                 config: SheetConfig | None = None, k_elastic: float | None = None) -> None:
        self.config = config or SheetConfig(n_layer=n_layer, thickness=thickness, dt=dt, slip_limit=slip_limit)
        warn_above_stable_dt(self.config.dt, STABLE_DT[0], "the PyBullet sheet", STABLE_DT[1])
        if not (isinstance(n_workers, int) and n_workers >= 1):
            raise ValueError(f"n_workers = {n_workers!r} must be a positive int")
        if not (isinstance(sequence_len, int) and sequence_len >= 1):
            raise ValueError(f"sequence_len = {sequence_len!r} must be a positive int")
        if stderr_tol_deg_s is not None and not (math.isfinite(stderr_tol_deg_s) and stderr_tol_deg_s > 0):
            raise ValueError("stderr_tol_deg_s must be a positive number or None")
        self.n_workers = n_workers
        self.k_elastic = k_elastic
        self.sequence_len = sequence_len
        self.stderr_tol_deg_s = stderr_tol_deg_s
        self._client: Client | None = None
        self._pool: ProcessPoolExecutor | None = None

    def __repr__(self) -> str:
        c = self.config
        return f"PyBulletPhysics(dt={c.dt:g}, n_layer={c.n_layer}, n_workers={self.n_workers})"

    @property
    def dt(self) -> float:
        return self.config.dt

    def units(self, probes: Sequence[ProbeSpec]) -> list[list[ProbeSpec]]:
        """Split the probes into units (consecutive, same object and placement, at most ``sequence_len``)."""
        units: list[list[ProbeSpec]] = []
        for s in probes:
            first = units[-1][0] if units else None
            if (first is not None and first.obj == s.obj and len(units[-1]) < self.sequence_len
                    and (first.initial_yaw, first.initial_offset) == (s.initial_yaw, s.initial_offset)):
                units[-1].append(s)
            else:
                units.append([s])
        return units

    def check(self, probes: Sequence[ProbeSpec]) -> None:
        """Refuse (ProbeRefused) a probe of more than MAX_PROBE_STEPS time steps, before any work."""
        check_step_counts(check_probes(probes), self.config.dt)

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        """Simulate the probes and return one result per probe, in order (all checked first)."""
        probes = check_probes(probes)
        self.check(probes)
        if not probes:
            return []
        units = self.units(probes)
        bar = None
        if progress:
            from plate_env.core.progress import progress_bar

            bar = progress_bar(len(probes), "probes", "probe")
        results: list[ProbeResult] = []
        try:
            args = [(u, self.config, self.stderr_tol_deg_s, self.k_elastic) for u in units]
            if self.n_workers == 1 or len(units) == 1:
                if self._client is None:
                    self._client = Client()
                for u, a in zip(units, args, strict=True):
                    results.extend(run_unit(self._client, *a))
                    if bar is not None:
                        bar.update(len(u))
            else:
                if self._pool is None:
                    import multiprocessing as mp

                    self._pool = ProcessPoolExecutor(max_workers=self.n_workers,
                                                     mp_context=mp.get_context("spawn"))
                for u, res in zip(units, self._pool.map(_worker_unit, args), strict=True):
                    results.extend(res)
                    if bar is not None:
                        bar.update(len(u))
        finally:
            if bar is not None:
                bar.close()
        return results

    def close(self) -> None:
        """Disconnect the client and shut the pool down. Safe to call twice."""
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:  # noqa: BLE001
            pass
