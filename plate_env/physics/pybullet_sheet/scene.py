"""One PyBullet scene: a driven plate and a two-layer tetrahedral mass-spring sheet; runs probes in sequence.

Measured PyBullet facts this relies on (``/work/shared/notes/physics-facts.md``): only the deformable world
honours friction and spring stiffness; the soft body's ``frictionCoeff`` (default 0!) times the plate's
``lateralFriction`` is the one Coulomb coefficient (no static/kinetic split: we use ``mu_s``); the plate must be
a fixed-base multibody whose joints are set with position AND velocity every step; soft bodies fall asleep
unless sleeping is disabled; node velocities are not readable, so we read positions only.

pybullet is imported lazily, only when a client is opened.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from plate_env.core.motion import plate_state
from plate_env.core.objects import ObjectSpec
from plate_env.core.probe import (
    FOLDED,
    LEFT_PLATE,
    NON_FINITE,
    OVERTURNED,
    RUNAWAY,
    SLIP_LIMIT_M,
    SLIPPED,
    ProbeResult,
    ProbeSpec,
    YawTrace,
)
from plate_env.core.streams import fd_redirected
from plate_env.physics.measure import measure_omega_b
from plate_env.physics.pybullet_sheet.mesh import SheetMesh, make_sheet, write_temp_vtk

GRAVITY = 9.81  #: m/s^2


@dataclass(frozen=True)
class SheetConfig:
    """Numerical and geometric choices of the PyBullet sheet (SI units).

    Attributes:
        n_layer: mesh points per layer (the sheet has ``2 n_layer`` nodes).
        thickness: layer gap, m.
        dt: time step, s.
        margin: soft-body collision margin, m.
        damping_time: spring damping ``springDampingStiffness = damping_time * k_elastic``, s (stiffness-
            proportional damping: the same damping ratio for a mode of a given frequency whatever ``k``).
        bending_ratio: ``springBendingStiffness / springElasticStiffness`` (PyBullet always applies its bending
            springs in mass-spring mode; with 0 the frequency no longer followed sqrt(k) cleanly).
        plate_half: half side of the square plate, m.
        plate_half_thick: half thickness of the plate box, m.
        record_every_s: how often node positions are read back (yaw, centre, stability checks), s.
        slip_limit: centre distance from the plate centre (plate frame) that makes a probe unstable, m.
    """

    n_layer: int = 91
    thickness: float = 0.002
    dt: float = 4e-4
    margin: float = 5e-4
    damping_time: float = 2e-4
    bending_ratio: float = 1.0
    plate_half: float = 0.1
    plate_half_thick: float = 0.005
    record_every_s: float = 2e-3
    slip_limit: float = SLIP_LIMIT_M

    def __post_init__(self) -> None:
        if not (isinstance(self.n_layer, int) and 8 <= self.n_layer <= 2000):
            raise ValueError(f"n_layer = {self.n_layer!r} must be an int in [8, 2000]")
        for label, value, lo, hi in (("dt", self.dt, 0.0, 0.01), ("thickness", self.thickness, 0.0, 0.05),
                                     ("margin", self.margin, 0.0, 0.01),
                                     ("damping_time", self.damping_time, -1e-12, 1.0),
                                     ("record_every_s", self.record_every_s, 0.0, 0.1),
                                     ("slip_limit", self.slip_limit, 0.0, 1.0)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and lo < value <= hi):
                raise ValueError(f"SheetConfig {label} = {value!r} is outside ({lo}, {hi}]")

    @property
    def record_every(self) -> int:
        """Steps between read-backs."""
        return max(1, round(self.record_every_s / self.dt))


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Send what C code prints on file descriptor 1 during the block to /dev/null: PyBullet's ``loadSoftBody``
    prints its mesh counts ("Nodes: 182 ...") there, and stdout is for results (``--json``). C's stdio buffer is
    flushed before fd 1 is restored, so nothing surfaces later. Output of other threads during the block is lost
    too; the blocks are single PyBullet calls."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        with fd_redirected(1, devnull):
            yield
    finally:
        os.close(devnull)


class Client:
    """A PyBullet DIRECT client owned by one process (opened lazily, closed explicitly or at exit)."""

    def __init__(self) -> None:
        import pybullet as p

        self.p = p
        self.cid = p.connect(p.DIRECT)

    def close(self) -> None:
        if self.cid is not None and self.cid >= 0:
            try:
                self.p.disconnect(physicsClientId=self.cid)
            except Exception:  # noqa: BLE001 - already gone
                pass
        self.cid = None


class SheetScene:
    """Plate + sheet in a deformable world, built once per object and reused by a sequence of probes.

    Args:
        client: the process's PyBullet client (the simulation is reset, not reconnected).
        obj: the object (mass, diameter, mu_s are used; omega_n only through ``k_elastic``).
        k_elastic: ``springElasticStiffness`` of every tetrahedron edge (from the calibration).
        config: numerical choices.
        gravity: m/s^2 (the ring-down test switches it).
        initial_yaw, initial_offset: the sheet's yaw (rad) and centre offset (u, v in m, plate frame, which is the
            world frame of the flat plate at rest) when built: a probe's ``ProbeSpec.initial_yaw/initial_offset``.
    """

    def __init__(self, client: Client, obj: ObjectSpec, k_elastic: float, config: SheetConfig,
                 gravity: float = GRAVITY, initial_yaw: float = 0.0,
                 initial_offset: tuple[float, float] = (0.0, 0.0), with_plate: bool = True) -> None:
        self.client, self.obj, self.k_elastic, self.config = client, obj, float(k_elastic), config
        p, cid = client.p, client.cid
        self.p, self.cid = p, cid
        p.resetSimulation(p.RESET_USE_DEFORMABLE_WORLD, physicsClientId=cid)
        p.setGravity(0.0, 0.0, -gravity, physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=config.dt, numSubSteps=0, physicsClientId=cid)
        self.mesh: SheetMesh = make_sheet(config.n_layer, obj.diameter, config.thickness)
        yaw0, (dx, dy) = initial_yaw, initial_offset
        c, s = math.cos(yaw0), math.sin(yaw0)
        self.plate = -1
        if with_plate:
            self.plate = self._make_plate()
        path = write_temp_vtk(self.mesh)
        try:
            base = (dx, dy, config.margin + 1e-4)
            orn = p.getQuaternionFromEuler((0.0, 0.0, yaw0))
            with quiet_stdout():
                self.body = p.loadSoftBody(
                    path, basePosition=base, baseOrientation=orn, mass=obj.mass, useMassSpring=1, useNeoHookean=0,
                    useBendingSprings=0, springElasticStiffness=self.k_elastic,
                    springDampingStiffness=config.damping_time * self.k_elastic,
                    springBendingStiffness=config.bending_ratio * self.k_elastic,
                    springDampingAllDirections=0, useSelfCollision=0, frictionCoeff=obj.mu_s,
                    collisionMargin=config.margin, useFaceContact=1, physicsClientId=cid)
        finally:
            os.remove(path)
        if self.body < 0:
            raise RuntimeError("PyBullet could not load the sheet")
        p.changeDynamics(self.body, -1, activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
        rot = np.array([[c, -s], [s, c]])
        self.rest_xy = self.mesh.nodes[:, :2] @ rot.T
        self.rest_xy = self.rest_xy - self.rest_xy.mean(axis=0)
        self.rest_gyr = float(np.sqrt((self.rest_xy ** 2).sum(axis=1).mean()))
        self.n_layer = self.mesh.n_layer
        self.alive = True

    # ------------------------------------------------------------------ build
    def _make_plate(self) -> int:
        p, cid, cfg = self.p, self.cid, self.config
        box = p.createCollisionShape(p.GEOM_BOX, halfExtents=(cfg.plate_half, cfg.plate_half, cfg.plate_half_thick),
                                     collisionFramePosition=(0.0, 0.0, -cfg.plate_half_thick), physicsClientId=cid)
        plate = p.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1, basePosition=(0.0, 0.0, 0.0),
            linkMasses=[1.0, 1.0], linkCollisionShapeIndices=[-1, box], linkVisualShapeIndices=[-1, -1],
            linkPositions=[(0.0, 0.0, 0.0), (0.0, 0.0, 0.0)], linkOrientations=[(0, 0, 0, 1), (0, 0, 0, 1)],
            linkInertialFramePositions=[(0.0, 0.0, 0.0), (0.0, 0.0, 0.0)],
            linkInertialFrameOrientations=[(0, 0, 0, 1), (0, 0, 0, 1)], linkParentIndices=[0, 1],
            linkJointTypes=[p.JOINT_PRISMATIC, p.JOINT_REVOLUTE], linkJointAxis=[(1, 0, 0), (1, 0, 0)],
            useMaximalCoordinates=0, physicsClientId=cid)
        for j in (0, 1):
            p.setJointMotorControl2(plate, j, p.VELOCITY_CONTROL, force=0.0, physicsClientId=cid)
        p.changeDynamics(plate, 1, lateralFriction=1.0, physicsClientId=cid)
        p.changeDynamics(plate, -1, activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=cid)
        return plate

    # ------------------------------------------------------------------ state
    def positions(self) -> np.ndarray:
        """(N, 3) node positions, m (world frame)."""
        _, verts = self.p.getMeshData(self.body, -1, flags=self.p.MESH_DATA_SIMULATION_MESH,
                                      physicsClientId=self.cid)
        return np.asarray(verts, dtype=float)

    def set_plate(self, theta: float, theta_dot: float, x: float, x_dot: float) -> None:
        self.p.resetJointState(self.plate, 0, x, x_dot, physicsClientId=self.cid)
        self.p.resetJointState(self.plate, 1, theta, theta_dot, physicsClientId=self.cid)

    def step(self) -> None:
        self.p.stepSimulation(physicsClientId=self.cid)

    # ------------------------------------------------------------------ probes
    def run_probe(self, spec: ProbeSpec, stderr_tol_deg_s: float | None = None,
                  min_periods: int = 8) -> ProbeResult:
        """Drive the plate with ``spec.motion`` from plate time 0 (its ramp starts from rest) and measure omega_B.

        The sheet continues from whatever state the previous probe left it in. Stops early, at a period
        boundary after at least ``min_periods`` measured periods, when the standard error of omega_B falls below
        ``stderr_tol_deg_s`` (deg/s). Never raises for a physical failure: the result is flagged unstable.
        """
        cfg, mot = self.config, spec.motion
        dt, rec = cfg.dt, cfg.record_every
        n_steps = math.ceil(spec.duration_s / dt - 1e-9)
        period = 1.0 / mot.freq_hz
        t0m = spec.measure_start_s
        vlim = 3.0 * mot.peak_speed(self.obj.radius) + 1.0
        ts: list[float] = [0.0]
        yaws: list[float] = [0.0]
        cus: list[float] = []
        cvs: list[float] = []
        x_prev = self.positions()
        th, _, xp, _ = plate_state(0.0, mot.freq_hz, mot.amp_rad, mot.b_p, mot.ramp_s)
        yaw_prev, cu, cv = self._frame(x_prev, th, xp)[:3]
        cus.append(cu)
        cvs.append(cv)
        yaw_unwrapped = 0.0
        reason: str | None = None
        wall0 = time.perf_counter()
        next_check_period = min_periods
        steps_done = 0
        for i in range(n_steps):
            th, thd, xp, xpd = plate_state(i * dt, mot.freq_hz, mot.amp_rad, mot.b_p, mot.ramp_s)
            self.set_plate(th, thd, xp, xpd)
            self.step()
            steps_done = i + 1
            if steps_done % rec and steps_done != n_steps:
                continue
            t = steps_done * dt
            x = self.positions()
            if not np.isfinite(x).all():
                reason = NON_FINITE
                break
            th, _, xp, _ = plate_state(t, mot.freq_hz, mot.amp_rad, mot.b_p, mot.ramp_s)
            yaw, cu, cv, cw, up, gyr = self._frame(x, th, xp)
            d = yaw - yaw_prev
            yaw_unwrapped += (d + math.pi) % (2.0 * math.pi) - math.pi
            yaw_prev = yaw
            ts.append(t)
            yaws.append(yaw_unwrapped)
            cus.append(cu)
            cvs.append(cv)
            reason = self._check(x, x_prev, cu, cv, cw, up, gyr, vlim, ts)
            x_prev = x
            if reason is not None:
                break
            if stderr_tol_deg_s is not None and t > t0m:
                done = int(math.floor((t - t0m) / period + 1e-9))
                if done >= next_check_period and done < spec.n_periods:
                    next_check_period = done + 1
                    _, se, _ = measure_omega_b(np.asarray(ts), np.asarray(yaws), t0m, period, done)
                    if math.degrees(se) < stderr_tol_deg_s:
                        break
        wall = time.perf_counter() - wall0
        t_arr, y_arr = np.asarray(ts), np.asarray(yaws)
        unstable = reason is not None
        if unstable:
            self.alive = False
        t_end = float(t_arr[-1])
        omega, se, used = measure_omega_b(t_arr, y_arr, t0m, period, spec.n_periods, t_end)
        if not (math.isfinite(omega) and math.isfinite(se)):
            omega, se, used = 0.0, 0.0, 0
        trace = None
        if spec.record_trace:
            trace = YawTrace(t=t_arr, yaw=y_arr, centre_u=np.asarray(cus), centre_v=np.asarray(cvs))
        return ProbeResult(spec=spec, omega_b_deg_s=math.degrees(omega), stderr_deg_s=math.degrees(se),
                           unstable=unstable, reason=reason, sim_s=float(steps_done * dt), wall_s=wall,
                           periods_measured=used, trace=trace)

    def _frame(self, x: np.ndarray, theta: float,
               plate_x: float) -> tuple[float, float, float, float, tuple[float, float], float]:
        """Yaw (rad, wrapped), centre (u, v, w) (m, plate frame), (handedness, layer gap m), in-plane gyration (m).

        The handedness is the determinant of the 2D cross-covariance between the rest and current node patterns: it
        turns negative when the disc lies upside down (mirrored seen from above).
        """
        c, s = math.cos(theta), math.sin(theta)
        d = x - np.array([plate_x, 0.0, 0.0])
        u = d[:, 0]
        v = d[:, 1] * c + d[:, 2] * s
        w = -d[:, 1] * s + d[:, 2] * c
        cu, cv, cw = float(u.mean()), float(v.mean()), float(w.mean())
        qu, qv = u - cu, v - cv
        r = self.rest_xy
        cross = float((r[:, 0] * qv - r[:, 1] * qu).sum())
        dot = float((r[:, 0] * qu + r[:, 1] * qv).sum())
        yaw = math.atan2(cross, dot)
        nl = self.n_layer
        # handedness of the in-plane node pattern: < 0 when the disc lies mirrored, i.e. upside down
        det = float((r[:, 0] * qu).sum() * (r[:, 1] * qv).sum() - (r[:, 1] * qu).sum() * (r[:, 0] * qv).sum())
        gap = float(w[nl:].mean() - w[:nl].mean())  # top layer minus bottom layer, m
        gyr = float(np.sqrt((qu * qu + qv * qv).mean()))
        return yaw, cu, cv, cw, (det, gap), gyr

    def _check(self, x: np.ndarray, x_prev: np.ndarray, cu: float, cv: float, cw: float,
               shape: tuple[float, float], gyr: float, vlim: float, ts: list[float]) -> str | None:
        """The reason constant of a failure, or None.

        ``shape`` is (handedness, layer gap m): a mirrored pattern means overturned; a layer gap below a quarter of
        the thickness means the sheet collapsed through its own thickness (tetrahedra inverted): reported as
        ``folded``.
        """
        cfg = self.config
        if math.hypot(cu, cv) > cfg.slip_limit:
            return SLIPPED
        if shape[0] < 0.0:
            return OVERTURNED
        if shape[1] < 0.25 * cfg.thickness:
            return FOLDED
        if cw > 0.1 or cw < -0.02:
            return LEFT_PLATE
        dt_rec = ts[-1] - ts[-2] if len(ts) >= 2 else cfg.record_every_s
        step_max = float(np.sqrt(((x - x_prev) ** 2).sum(axis=1)).max())
        if step_max > vlim * max(dt_rec, 1e-9) or gyr > 2.0 * self.rest_gyr:
            return RUNAWAY
        if gyr < 0.5 * self.rest_gyr:
            return FOLDED
        return None
