"""numba kernels for the tile-link models: the whole time loop of a probe in one compiled call.

Importing this module imports numba (~0.5 s); the first call compiles (cached on disk afterwards).
A batch runs its probes in parallel threads (``prange``); each probe's arithmetic is the same as when it runs
alone, so a batch gives bit-identical numbers to single runs.

Compiled and cached code are the same code. numba links a copy of every jitted function a kernel calls into the
kernel's own object code (a weak symbol, optimised again there); in a process that compiles, the kernel's calls
bind to the callee's own, earlier compiled copy instead, in a process that loads the disk cache to the embedded
one. With ``reassoc``/``nsz`` the two copies round differently (measured: the yaw trace differed from the first
millisecond, omega_B by up to ~0.4 % over a 1.6 s probe). So the small helpers are inlined at numba's IR level
(no copy to bind), and :func:`load_first` loads a batch kernel's per-probe kernel before the batch kernel, so that
both kinds of process bind the batch's calls to the same, standalone copy (``tests/test_determinism.py``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from plate_env.core.motion import plate_state as _plate_state_py
from plate_env.core.probe import Status
from plate_env.physics.tilelink import params
from plate_env.physics.tilelink.contact import damped_normal_force as _damped_normal_force_py
from plate_env.physics.tilelink.contact import friction_scale as _friction_scale_py
from plate_env.physics.tilelink.contact import spring_force as _spring_force_py
from plate_env.physics.tilelink.jit_cache import CACHE

plate_state = numba.njit(cache=CACHE, inline="always")(_plate_state_py)
spring_force = numba.njit(cache=CACHE, inline="always")(_spring_force_py)
damped_normal_force = numba.njit(cache=CACHE, inline="always")(_damped_normal_force_py)
friction_scale = numba.njit(cache=CACHE, inline="always")(_friction_scale_py)


@numba.njit(cache=CACHE, inline="always")
def plate_at(prm, t):
    """The plate's ``(theta, theta_dot, x, x_dot)`` at time ``t`` (s) for a probe's parameter vector ``prm``
    (:func:`plate_env.core.motion.plate_state` of its frequency, amplitudes and ramp); every kernel's one call."""
    return plate_state(t, prm[params.P_FREQ], prm[params.P_AMP], prm[params.P_BP], prm[params.P_RAMP])

#: fastmath without the no-NaN/no-inf assumptions, so blow-ups are still detected.
FAST = {"reassoc", "contract", "arcp", "nsz", "afn"}


@numba.njit(cache=CACHE, inline="always")
def observe(pos, rest, cells, x_plate, s_th, c_th, prev_yaw):
    """Plate-frame centre (u, v, w), unwrapped yaw about the plate normal, the disc normal's w and max |w|.

    ``pos``: (N, 3) world positions of the tile centres; ``rest``: (N, 2) their rest positions about the centre.
    Yaw is the 2D Procrustes angle between the rest layout and the current one, unwrapped against ``prev_yaw``.
    """
    n = pos.shape[0]
    cu = 0.0
    cv = 0.0
    cw = 0.0
    for i in range(n):
        cu += pos[i, 0] - x_plate
        cv += pos[i, 1] * c_th + pos[i, 2] * s_th
        cw += -pos[i, 1] * s_th + pos[i, 2] * c_th
    cu /= n
    cv /= n
    cw /= n
    sn = 0.0
    cs = 0.0
    for i in range(n):
        ru = pos[i, 0] - x_plate - cu
        rv = pos[i, 1] * c_th + pos[i, 2] * s_th - cv
        sn += rest[i, 0] * rv - rest[i, 1] * ru
        cs += rest[i, 0] * ru + rest[i, 1] * rv
    yaw = math.atan2(sn, cs)
    yaw += 2.0 * math.pi * round((prev_yaw - yaw) / (2.0 * math.pi))
    # area-weighted normal's plate-normal component from the cells' diagonals
    nw = 0.0
    for k in range(cells.shape[0]):
        a, b, c, d = cells[k, 0], cells[k, 1], cells[k, 2], cells[k, 3]
        d1u = pos[c, 0] - pos[a, 0]
        d1v = (pos[c, 1] - pos[a, 1]) * c_th + (pos[c, 2] - pos[a, 2]) * s_th
        d2u = pos[d, 0] - pos[b, 0]
        d2v = (pos[d, 1] - pos[b, 1]) * c_th + (pos[d, 2] - pos[b, 2]) * s_th
        nw += d1u * d2v - d1v * d2u
    return cu, cv, cw, yaw, nw


@numba.njit(cache=CACHE, inline="always")
def check_state(cu, cv, cw, nw, vmax2, prm):
    """The :class:`Status` of one observation (``Status.OK``: fine)."""
    if not (math.isfinite(cu) and math.isfinite(cv) and math.isfinite(cw) and math.isfinite(vmax2)):
        return Status.NON_FINITE
    if vmax2 > prm[params.P_VLIM] * prm[params.P_VLIM]:
        return Status.RUNAWAY
    if nw <= 0.0:
        return Status.OVERTURNED
    if cw > 0.05 or cw < -0.005:
        return Status.LEFT_PLATE
    if cu * cu + cv * cv > prm[params.P_SLIP] * prm[params.P_SLIP]:
        return Status.SLIPPED
    return Status.OK


@numba.njit(cache=CACHE, inline="always")
def record(x, rest, cells, x_plate, s_th, c_th, prev_yaw, vmax2, extra_status, prm, yaw_out, cu_out, cv_out, n_rec):
    """One record of any tile-link kernel: observe, check (``check_state`` first, then the model's own
    ``extra_status``) and, if still fine, write yaw and centre. Returns (status, yaw, records written)."""
    cu, cv, cw, yaw, nw = observe(x, rest, cells, x_plate, s_th, c_th, prev_yaw)
    status = check_state(cu, cv, cw, nw, vmax2, prm)
    if status == Status.OK:
        status = extra_status
    if status == Status.OK:
        yaw_out[n_rec] = yaw
        cu_out[n_rec] = cu
        cv_out[n_rec] = cv
        n_rec += 1
    return status, yaw, n_rec


@numba.njit(cache=CACHE, fastmath=FAST)
def pointmass_probe(prm, ainv, rest, links, diagonals, triplets, cells, yaw_out, cu_out, cv_out):
    """Simulate one point-mass probe; fills the traces and returns (status, records written)."""
    n = rest.shape[0]
    m = prm[params.P_MASS]
    inv_m = 1.0 / m
    kb = prm[params.P_KB]
    kin = prm[params.P_KIN]
    cin = prm[params.P_CIN]
    dt = prm[params.P_DT]
    grav = prm[params.P_G]
    n_steps = int(prm[params.P_NSTEPS])
    rec_every = int(prm[params.P_RECEVERY])
    spacing = math.sqrt((rest[links[0, 1], 0] - rest[links[0, 0], 0]) ** 2
                        + (rest[links[0, 1], 1] - rest[links[0, 0], 1]) ** 2)
    diag_len = spacing * math.sqrt(2.0)
    x = np.empty((n, 3))
    v = np.zeros((n, 3))
    f = np.empty((n, 3))
    vs = np.empty((n, 3))
    cy = math.cos(prm[params.P_YAW0])
    sy = math.sin(prm[params.P_YAW0])
    for i in range(n):
        x[i, 0] = prm[params.P_U0] + cy * rest[i, 0] - sy * rest[i, 1]
        x[i, 1] = prm[params.P_V0] + sy * rest[i, 0] + cy * rest[i, 1]
        x[i, 2] = -prm[params.P_DEPTH0]
    yaw = prm[params.P_YAW0]
    n_rec = 0
    status = Status.OK
    for step in range(n_steps + 1):
        t = step * dt
        th, th_dot, xp, xp_dot = plate_at(prm, t)
        s_th = math.sin(th)
        c_th = math.cos(th)
        if step % rec_every == 0:
            vmax2 = 0.0
            for i in range(n):
                sp = v[i, 0] ** 2 + v[i, 1] ** 2 + v[i, 2] ** 2
                if not (sp <= vmax2):
                    vmax2 = sp
            status, yaw, n_rec = record(x, rest, cells, xp, s_th, c_th, yaw, vmax2, Status.OK, prm, yaw_out, cu_out,
                                        cv_out, n_rec)
            if status != Status.OK:
                break
        if step == n_steps:
            break
        # forces: gravity, bending (explicit stiffness), in-plane spring-dampers
        for i in range(n):
            f[i, 0] = 0.0
            f[i, 1] = 0.0
            f[i, 2] = -m * grav
        for k in range(triplets.shape[0]):
            a, b, c = triplets[k, 0], triplets[k, 1], triplets[k, 2]
            for d in range(3):
                kap = kb * (x[a, d] - 2.0 * x[b, d] + x[c, d])
                f[a, d] -= kap
                f[b, d] += 2.0 * kap
                f[c, d] -= kap
        for pairs, rest_len in ((links, spacing), (diagonals, diag_len)):
            for k in range(pairs.shape[0]):
                a, b = pairs[k, 0], pairs[k, 1]
                dx = x[b, 0] - x[a, 0]
                dy = x[b, 1] - x[a, 1]
                dz = x[b, 2] - x[a, 2]
                ln = math.sqrt(dx * dx + dy * dy + dz * dz)
                ex, ey, ez = dx / ln, dy / ln, dz / ln
                vrel = (v[b, 0] - v[a, 0]) * ex + (v[b, 1] - v[a, 1]) * ey + (v[b, 2] - v[a, 2]) * ez
                fs = kin * (ln - rest_len) + cin * vrel
                f[a, 0] += fs * ex
                f[a, 1] += fs * ey
                f[a, 2] += fs * ez
                f[b, 0] -= fs * ex
                f[b, 1] -= fs * ey
                f[b, 2] -= fs * ez
        for i in range(n):
            for d in range(3):
                vs[i, d] = v[i, d] + dt * inv_m * f[i, d]
        # bending damper, implicit: v = (I + dt eta kb/m L)^-1 vs
        for i in range(n):
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for j in range(n):
                w = ainv[i, j]
                a0 += w * vs[j, 0]
                a1 += w * vs[j, 1]
                a2 += w * vs[j, 2]
            v[i, 0] = a0
            v[i, 1] = a1
            v[i, 2] = a2
        # plate contact at every node: implicit normal damper, Coulomb stick/slip
        for i in range(n):
            w_i = -x[i, 1] * s_th + x[i, 2] * c_th
            if w_i >= 0.0:
                continue
            pvx = xp_dot
            pvy = -th_dot * x[i, 2]
            pvz = th_dot * x[i, 1]
            rx = v[i, 0] - pvx
            ry = v[i, 1] - pvy
            rz = v[i, 2] - pvz
            vn = -ry * s_th + rz * c_th
            fn = damped_normal_force(spring_force(-w_i, prm[params.P_KC]), vn, prm[params.P_CC], inv_m, dt)
            if fn <= 0.0:
                continue
            vn_new = vn + dt * inv_m * fn
            tx = rx
            ty = ry + vn * s_th
            tz = rz - vn * c_th
            slip = math.sqrt(tx * tx + ty * ty + tz * tz)
            sc = friction_scale(slip, fn, prm[params.P_MUS], prm[params.P_MUK], prm[params.P_VT], inv_m, dt)
            v[i, 0] = pvx + sc * tx
            v[i, 1] = pvy + sc * ty - vn_new * s_th
            v[i, 2] = pvz + sc * tz + vn_new * c_th
        for i in range(n):
            for d in range(3):
                x[i, d] += dt * v[i, d]
    return status, n_rec


@numba.njit(cache=CACHE, parallel=True)
def pointmass_batch_parallel(prm, ainv, rest, links, diagonals, triplets, cells, yaw_out, cu_out, cv_out,
                             status_out, nrec_out):
    """Run a batch of probes over threads (one probe per iteration)."""
    for b in numba.prange(prm.shape[0]):
        s, r = pointmass_probe(prm[b], ainv[b], rest[b], links, diagonals, triplets, cells,
                               yaw_out[b], cu_out[b], cv_out[b])
        status_out[b] = s
        nrec_out[b] = r


@numba.njit(cache=CACHE)
def pointmass_batch_serial(prm, ainv, rest, links, diagonals, triplets, cells, yaw_out, cu_out, cv_out,
                           status_out, nrec_out):
    """The same batch on the calling thread (no threading overhead for single probes)."""
    for b in range(prm.shape[0]):
        s, r = pointmass_probe(prm[b], ainv[b], rest[b], links, diagonals, triplets, cells,
                               yaw_out[b], cu_out[b], cv_out[b])
        status_out[b] = s
        nrec_out[b] = r


def load_first(dispatcher, *args) -> None:
    """Compile (or load from the disk cache) ``dispatcher`` for the types of ``args``; call it before running a
    kernel that calls ``dispatcher``, so the kernel binds to this copy whether it was compiled or cached."""
    dispatcher.compile(tuple(numba.typeof(a) for a in args))
