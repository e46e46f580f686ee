"""numba kernels for the rigid-tile model (:mod:`plate_env.physics.tilelink.rigid`): a probe's whole time loop.

Integrator (one step of ``dt`` s, semi-implicit):

1. gravity and the gyroscopic torque ``-w x (I w)`` update each tile's velocity and angular velocity;
2. the joint rows' accumulated impulses of the previous step are applied again (warm start);
3. plate contact at every tile corner: the shared Eqs. (3)-(4) law (:func:`contact.spring_force` once per step,
   :func:`contact.damped_normal_force` with its implicit damper in the corner's effective mass per sweep,
   :func:`contact.friction_scale` stick/slip), impulses acting on the tile's translation and rotation. The geometry
   is frozen for the step, so each active corner's spring force ``k a^2.2``, effective normal mass and rotational
   response are computed once per step, not per sweep. Corners are visited corner-major and joints in four colour
   classes (:func:`rigid.joint_order`) so that consecutive updates touch different tiles;
4. ``iterations`` block Gauss-Seidel sweeps over the 88 joints: every row (compression, rigid edge/normal
   translation, bending, rigid rotation about the normal) is a spring-damper integrated implicitly (backward
   Euler "soft constraint": ``J v' + k C / (dt k + c) + P / (dt (dt k + c)) = 0``), the 3 translation rows and
   the 2 rotation rows of a joint solved together. Stiff rows therefore do not bound the step. The blocks'
   inverses are rebuilt every ``block_refresh`` steps (they set the convergence rate, not the fixed point);
5. positions and unit quaternions advance with the new velocities.

Checks every record (~1 ms): the point-mass model's :func:`kernels.check_state` (NaN, speed limit, overturned,
left plate, slipped), FOLDED (a joint bent beyond ``fold_angle`` or a tile upside down) and RUNAWAY by energy: the
disc's kinetic + gravitational + joint-elastic + contact-elastic energy may not exceed its start value plus the
work the plate has done on it (contact impulses times the plate's surface velocity) beyond a tolerance.

Importing this module imports numba; the first call compiles (cached on disk afterwards). Batches run one probe
per thread (``prange``) with the same arithmetic as a single run, so batch and single results are identical.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from functools import lru_cache

import numba
import numpy as np

from plate_env.core.probe import SLIP_LIMIT_M, ProbeSpec, Status
from plate_env.physics.tilelink import contact
from plate_env.physics.tilelink.contact import PAPER_CONTACT, ContactLaw
from plate_env.physics.tilelink.jit_cache import CACHE
from plate_env.physics.tilelink.kernels import (
    FAST,
    damped_normal_force,
    friction_scale,
    load_first,
    plate_state,
    record,
    spring_force,
)
from plate_env.physics.tilelink.params import (
    DEFAULT_DT,
    DEFAULT_RECORD_INTERVAL_S,
    N_PARAMS,
    P_AMP,
    P_BP,
    P_CC,
    P_CIN,
    P_DEPTH0,
    P_DT,
    P_FREQ,
    P_G,
    P_KB,
    P_KC,
    P_KIN,
    P_MASS,
    P_MUK,
    P_MUS,
    P_NSTEPS,
    P_RAMP,
    P_RECEVERY,
    P_U0,
    P_V0,
    P_VT,
    P_YAW0,
    allocate_outputs,
    common_vector,
)
from plate_env.physics.tilelink.rigid import RigidTileConfig, RigidTileParams, build_params, joint_order

# Extra entries of the rigid parameter vector (after the point-mass layout, whose meaning they share:
# P_MASS tile mass, P_KB bending k_b, P_KIN/P_CIN compression row).
(R_H, R_IXX, R_IZZ, R_CB, R_KT2, R_CT2, R_KN, R_CN, R_KRN, R_CRN, R_NITER, R_FOLD, R_FOLDW, R_EREL, R_EABS,
 R_CORNERW, R_REFRESH) = range(N_PARAMS, N_PARAMS + 17)
N_RIGID_PARAMS = N_PARAMS + 17


@numba.njit(cache=CACHE, inline="always")
def _apply_inv_inertia(nx, ny, nz, ixx_inv, dinv, ux, uy, uz):
    """``I_world^-1 u`` of a thin symmetric plate with unit normal n: ``u / I_xx + (1/I_zz - 1/I_xx)(n.u) n``."""
    s = dinv * (nx * ux + ny * uy + nz * uz)
    return ux * ixx_inv + s * nx, uy * ixx_inv + s * ny, uz * ixx_inv + s * nz


@numba.njit(cache=CACHE, inline="always")
def _turn(w, i, lx, ly, lz, nx, ny, nz, ixx_inv, dinv):
    """Add ``I^-1 l`` to tile ``i``'s angular velocity (l: angular impulse, N m s; n: the tile's normal)."""
    dx, dy, dz = _apply_inv_inertia(nx, ny, nz, ixx_inv, dinv, lx, ly, lz)
    w[i, 0] += dx
    w[i, 1] += dy
    w[i, 2] += dz


@numba.njit(cache=CACHE, inline="always")
def _push(v, w, i, fx, fy, fz, rx, ry, rz, lx, ly, lz, nx, ny, nz, inv_m, ixx_inv, dinv):
    """Apply the impulse f (N s) at lever r (m) from the centre, plus the angular impulse l (N m s), to tile ``i``.
    Callers pass -f, -l for the other side of a joint."""
    v[i, 0] += fx * inv_m
    v[i, 1] += fy * inv_m
    v[i, 2] += fz * inv_m
    _turn(w, i, lx + (ry * fz - rz * fy), ly + (rz * fx - rx * fz), lz + (rx * fy - ry * fx), nx, ny, nz, ixx_inv,
          dinv)


@numba.njit(cache=CACHE, inline="always")
def _row_constants(prm, dt):
    """Each joint row's stiffness ``k`` (rows: 0 compression, 1 edge, 2 normal, 3 bending, 4 rotation about n) and
    the backward-Euler factors of its spring-damper: ``gamma = 1 / (dt (dt k + c))``, ``k / (dt k + c)``."""
    rk = np.empty(5)
    rc = np.empty(5)
    rk[0] = prm[P_KIN]
    rc[0] = prm[P_CIN]
    rk[1] = prm[R_KT2]
    rc[1] = prm[R_CT2]
    rk[2] = prm[R_KN]
    rc[2] = prm[R_CN]
    rk[3] = prm[P_KB]
    rc[3] = prm[R_CB]
    rk[4] = prm[R_KRN]
    rc[4] = prm[R_CRN]
    gam = np.empty(5)
    kfac = np.empty(5)
    for r in range(5):
        den = dt * rk[r] + rc[r]
        gam[r] = 1.0 / (dt * den)
        kfac[r] = rk[r] / den
    return rk, gam, kfac


@numba.njit(cache=CACHE, inline="always")
def _place_tiles(prm, rest, x, q):
    """The start state: flat at the rest depth, turned by the initial yaw, shifted by the initial offset."""
    cy = math.cos(prm[P_YAW0])
    sy = math.sin(prm[P_YAW0])
    for i in range(rest.shape[0]):
        x[i, 0] = prm[P_U0] + cy * rest[i, 0] - sy * rest[i, 1]
        x[i, 1] = prm[P_V0] + sy * rest[i, 0] + cy * rest[i, 1]
        x[i, 2] = -prm[P_DEPTH0]
        q[i, 0] = math.cos(0.5 * prm[P_YAW0])
        q[i, 3] = math.sin(0.5 * prm[P_YAW0])


@numba.njit(cache=CACHE, inline="always")
def _tile_axes(q, ax):
    """Each tile's axes in the world from its unit quaternion: e1 (0:3), e2 (3:6), normal (6:9)."""
    for i in range(q.shape[0]):
        qw, qx, qy, qz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        ax[i, 0] = 1.0 - 2.0 * (qy * qy + qz * qz)
        ax[i, 1] = 2.0 * (qx * qy + qw * qz)
        ax[i, 2] = 2.0 * (qx * qz - qw * qy)
        ax[i, 3] = 2.0 * (qx * qy - qw * qz)
        ax[i, 4] = 1.0 - 2.0 * (qx * qx + qz * qz)
        ax[i, 5] = 2.0 * (qy * qz + qw * qx)
        ax[i, 6] = 2.0 * (qx * qz + qw * qy)
        ax[i, 7] = 2.0 * (qy * qz - qw * qx)
        ax[i, 8] = 1.0 - 2.0 * (qx * qx + qy * qy)


@numba.njit(cache=CACHE, inline="always")
def _energy(x, v, w, ax, jc, rk, m, ixx, izz, grav, hh, kc, s_th, c_th):
    """(largest squared tile speed, the disc's mechanical energy in J, lowest plate-normal component of a tile
    normal). Energy: kinetic + gravitational + contact-spring (k/3.2 a^3.2 at each corner) + joint-elastic."""
    vmax2 = 0.0
    energy = 0.0
    tile_w_min = 1.0
    for i in range(x.shape[0]):
        sp = v[i, 0] ** 2 + v[i, 1] ** 2 + v[i, 2] ** 2
        if not (sp <= vmax2):
            vmax2 = sp
        nx, ny, nz = ax[i, 6], ax[i, 7], ax[i, 8]
        wn = nx * w[i, 0] + ny * w[i, 1] + nz * w[i, 2]
        energy += 0.5 * m * sp + 0.5 * (ixx * (w[i, 0] ** 2 + w[i, 1] ** 2 + w[i, 2] ** 2)
                                        + (izz - ixx) * wn * wn) + m * grav * x[i, 2]
        tw = -ny * s_th + nz * c_th
        if tw < tile_w_min:
            tile_w_min = tw
        for cnr in range(4):
            sa = hh if (cnr == 0 or cnr == 3) else -hh
            sb = hh if cnr < 2 else -hh
            py = x[i, 1] + sa * ax[i, 1] + sb * ax[i, 4]
            pz = x[i, 2] + sa * ax[i, 2] + sb * ax[i, 5]
            wc = -py * s_th + pz * c_th
            if wc < 0.0:
                energy += kc / (1.0 + contact.CONTACT_EXPONENT) * math.exp(
                    (1.0 + contact.CONTACT_EXPONENT) * math.log(-wc))
    for j in range(jc.shape[0]):
        for r in range(5):
            energy += 0.5 * rk[r] * jc[j, r] * jc[j, r]
    return vmax2, energy, tile_w_min


@numba.njit(cache=CACHE, inline="always")
def _check_and_record(step, prm, x, v, w, ax, jc, rk, rest, cells, xp, s_th, c_th, yaw, e0, work, work_abs,
                      excess_max, bend_max, yaw_out, cu_out, cv_out, n_rec):
    """Stage 1, every record: the energy check (RUNAWAY when the energy exceeds its start plus the plate's work
    beyond the tolerance), the fold check (FOLDED), then the shared observation and checks of
    :func:`kernels.record`. Returns (status, yaw, records written, E0, max excess, E - E0)."""
    m = prm[P_MASS]
    hh = 0.5 * prm[R_H]
    kc = prm[P_KC] * prm[R_CORNERW]
    vmax2, energy, tile_w_min = _energy(x, v, w, ax, jc, rk, m, prm[R_IXX], prm[R_IZZ], prm[P_G], hh, kc, s_th, c_th)
    if step == 0:
        e0 = energy
    excess = energy - e0 - work
    if excess > excess_max:
        excess_max = excess
    extra = Status.OK
    if bend_max > prm[R_FOLD] or tile_w_min < prm[R_FOLDW]:
        extra = Status.FOLDED
    elif not (excess <= prm[R_EREL] * work_abs + prm[R_EABS]):
        extra = Status.RUNAWAY
    status, yaw, n_rec = record(x, rest, cells, xp, s_th, c_th, yaw, vmax2, extra, prm, yaw_out, cu_out, cv_out,
                                n_rec)
    return status, yaw, n_rec, e0, excess_max, energy - e0


@numba.njit(cache=CACHE, inline="always")
def _gravity_and_gyroscopic(v, w, ax, dt, grav, ixx, izz, ixx_inv, dinv):
    """Integrator step 1 (explicit): gravity, and the gyroscopic torque ``-w x (I w)``."""
    for i in range(v.shape[0]):
        v[i, 2] -= dt * grav
        nx, ny, nz = ax[i, 6], ax[i, 7], ax[i, 8]
        wx, wy, wz = w[i, 0], w[i, 1], w[i, 2]
        wn = nx * wx + ny * wy + nz * wz
        # w x (I w) = (I_zz - I_xx)(n.w)(w x n)
        g = (izz - ixx) * wn
        tx = -g * (wy * nz - wz * ny)
        ty = -g * (wz * nx - wx * nz)
        tz = -g * (wx * ny - wy * nx)
        dx, dy, dz = _apply_inv_inertia(nx, ny, nz, ixx_inv, dinv, tx, ty, tz)
        w[i, 0] += dt * dx
        w[i, 1] += dt * dy
        w[i, 2] += dt * dz


@numba.njit(cache=CACHE, inline="always")
def _translation_block(j, rax, ray, raz, rbx, rby, rbz, nax, nay, naz, nbx, nby, nbz, t1x, t1y, t1z, t2x, t2y, t2z,
                       nnx, nny, nnz, inv_m, ixx_inv, dinv, gam, jkt):
    """Inverse of joint ``j``'s 3x3 translation block ``K = (2/m) I + sum (r x e_i) . I^-1 (r x e_j) + gamma``
    in the joint frame (t1, t2, n), stored as (xx, xy, xz, yy, yz, zz) in ``jkt[j]``."""
    k00 = 2.0 * inv_m + gam[0]
    k11 = 2.0 * inv_m + gam[1]
    k22 = 2.0 * inv_m + gam[2]
    k01 = 0.0
    k02 = 0.0
    k12 = 0.0
    for side in range(2):
        if side == 0:
            rx, ry, rz = rax, ray, raz
            px, py, pz = nax, nay, naz
        else:
            rx, ry, rz = rbx, rby, rbz
            px, py, pz = nbx, nby, nbz
        u0x = ry * t1z - rz * t1y
        u0y = rz * t1x - rx * t1z
        u0z = rx * t1y - ry * t1x
        u1x = ry * t2z - rz * t2y
        u1y = rz * t2x - rx * t2z
        u1z = rx * t2y - ry * t2x
        u2x = ry * nnz - rz * nny
        u2y = rz * nnx - rx * nnz
        u2z = rx * nny - ry * nnx
        i0x, i0y, i0z = _apply_inv_inertia(px, py, pz, ixx_inv, dinv, u0x, u0y, u0z)
        i1x, i1y, i1z = _apply_inv_inertia(px, py, pz, ixx_inv, dinv, u1x, u1y, u1z)
        i2x, i2y, i2z = _apply_inv_inertia(px, py, pz, ixx_inv, dinv, u2x, u2y, u2z)
        k00 += u0x * i0x + u0y * i0y + u0z * i0z
        k01 += u0x * i1x + u0y * i1y + u0z * i1z
        k02 += u0x * i2x + u0y * i2y + u0z * i2z
        k11 += u1x * i1x + u1y * i1y + u1z * i1z
        k12 += u1x * i2x + u1y * i2y + u1z * i2z
        k22 += u2x * i2x + u2y * i2y + u2z * i2z
    c00 = k11 * k22 - k12 * k12
    c01 = k02 * k12 - k01 * k22
    c02 = k01 * k12 - k02 * k11
    det = k00 * c00 + k01 * c01 + k02 * c02
    idet = 1.0 / det
    jkt[j, 0] = c00 * idet
    jkt[j, 1] = c01 * idet
    jkt[j, 2] = c02 * idet
    jkt[j, 3] = (k00 * k22 - k02 * k02) * idet
    jkt[j, 4] = (k01 * k02 - k00 * k12) * idet
    jkt[j, 5] = (k00 * k11 - k01 * k01) * idet


@numba.njit(cache=CACHE, inline="always")
def _rotation_block(j, nax, nay, naz, nbx, nby, nbz, t2x, t2y, t2z, nnx, nny, nnz, ixx_inv, dinv, gam, jkr):
    """Inverse of joint ``j``'s 2x2 rotation block over (t2, n): ``e_i . (Ia^-1 + Ib^-1) e_j + gamma``, stored
    as (xx, xy, yy) in ``jkr[j]``."""
    a2x, a2y, a2z = _apply_inv_inertia(nax, nay, naz, ixx_inv, dinv, t2x, t2y, t2z)
    b2x, b2y, b2z = _apply_inv_inertia(nbx, nby, nbz, ixx_inv, dinv, t2x, t2y, t2z)
    a3x, a3y, a3z = _apply_inv_inertia(nax, nay, naz, ixx_inv, dinv, nnx, nny, nnz)
    b3x, b3y, b3z = _apply_inv_inertia(nbx, nby, nbz, ixx_inv, dinv, nnx, nny, nnz)
    r00 = t2x * (a2x + b2x) + t2y * (a2y + b2y) + t2z * (a2z + b2z) + gam[3]
    r01 = t2x * (a3x + b3x) + t2y * (a3y + b3y) + t2z * (a3z + b3z)
    r11 = nnx * (a3x + b3x) + nny * (a3y + b3y) + nnz * (a3z + b3z) + gam[4]
    idet = 1.0 / (r00 * r11 - r01 * r01)
    jkr[j, 0] = r11 * idet
    jkr[j, 1] = -r01 * idet
    jkr[j, 2] = r00 * idet


@numba.njit(cache=CACHE, inline="always")
def _joint_setup(refresh, x, v, w, ax, links, link_dir, hh, inv_m, ixx_inv, dinv, gam, kfac, jra, jrb, jfr, jkt,
                 jkr, jb, jc, pacc, bend_max):
    """Stage 2, every step: each joint's frame (t1 along the link, n the mean normal, t2 = n x t1), lever arms,
    position errors C and bias ``k C / (dt k + c)``; when ``refresh``, its block inverses (they set Gauss-Seidel's
    convergence rate, not its fixed point); then the warm start (last step's impulses applied again).
    Returns the largest |bending angle| seen so far (rad)."""
    for j in range(links.shape[0]):
        a = links[j, 0]
        b = links[j, 1]
        o = 3 * link_dir[j]
        e1ax, e1ay, e1az = ax[a, o], ax[a, o + 1], ax[a, o + 2]
        e1bx, e1by, e1bz = ax[b, o], ax[b, o + 1], ax[b, o + 2]
        rax, ray, raz = hh * e1ax, hh * e1ay, hh * e1az
        rbx, rby, rbz = -hh * e1bx, -hh * e1by, -hh * e1bz
        t1x, t1y, t1z = e1ax + e1bx, e1ay + e1by, e1az + e1bz
        ln = math.sqrt(t1x * t1x + t1y * t1y + t1z * t1z)
        t1x /= ln
        t1y /= ln
        t1z /= ln
        nax, nay, naz = ax[a, 6], ax[a, 7], ax[a, 8]
        nbx, nby, nbz = ax[b, 6], ax[b, 7], ax[b, 8]
        nnx, nny, nnz = nax + nbx, nay + nby, naz + nbz
        dd = nnx * t1x + nny * t1y + nnz * t1z
        nnx -= dd * t1x
        nny -= dd * t1y
        nnz -= dd * t1z
        ln = math.sqrt(nnx * nnx + nny * nny + nnz * nnz)
        nnx /= ln
        nny /= ln
        nnz /= ln
        t2x = nny * t1z - nnz * t1y
        t2y = nnz * t1x - nnx * t1z
        t2z = nnx * t1y - nny * t1x
        jra[j, 0], jra[j, 1], jra[j, 2] = rax, ray, raz
        jrb[j, 0], jrb[j, 1], jrb[j, 2] = rbx, rby, rbz
        jfr[j, 0], jfr[j, 1], jfr[j, 2] = t1x, t1y, t1z
        jfr[j, 3], jfr[j, 4], jfr[j, 5] = t2x, t2y, t2z
        jfr[j, 6], jfr[j, 7], jfr[j, 8] = nnx, nny, nnz
        # position errors
        dx = x[b, 0] + rbx - x[a, 0] - rax
        dy = x[b, 1] + rby - x[a, 1] - ray
        dz = x[b, 2] + rbz - x[a, 2] - raz
        jc[j, 0] = dx * t1x + dy * t1y + dz * t1z
        jc[j, 1] = dx * t2x + dy * t2y + dz * t2z
        jc[j, 2] = dx * nnx + dy * nny + dz * nnz
        cx = nay * nbz - naz * nby
        cy = naz * nbx - nax * nbz
        cz = nax * nby - nay * nbx
        bend = math.atan2(cx * t2x + cy * t2y + cz * t2z, nax * nbx + nay * nby + naz * nbz)
        jc[j, 3] = bend
        if abs(bend) > bend_max:
            bend_max = abs(bend)
        cx = e1ay * e1bz - e1az * e1by
        cy = e1az * e1bx - e1ax * e1bz
        cz = e1ax * e1by - e1ay * e1bx
        jc[j, 4] = cx * nnx + cy * nny + cz * nnz
        for r in range(5):
            jb[j, r] = kfac[r] * jc[j, r]
        if refresh:
            _translation_block(j, rax, ray, raz, rbx, rby, rbz, nax, nay, naz, nbx, nby, nbz, t1x, t1y, t1z, t2x,
                               t2y, t2z, nnx, nny, nnz, inv_m, ixx_inv, dinv, gam, jkt)
            _rotation_block(j, nax, nay, naz, nbx, nby, nbz, t2x, t2y, t2z, nnx, nny, nnz, ixx_inv, dinv, gam, jkr)
        # warm start: apply last step's impulses
        p0, p1, p2, p3, p4 = pacc[j, 0], pacc[j, 1], pacc[j, 2], pacc[j, 3], pacc[j, 4]
        fx = p0 * t1x + p1 * t2x + p2 * nnx
        fy = p0 * t1y + p1 * t2y + p2 * nny
        fz = p0 * t1z + p1 * t2z + p2 * nnz
        lx = p3 * t2x + p4 * nnx
        ly = p3 * t2y + p4 * nny
        lz = p3 * t2z + p4 * nnz
        _push(v, w, a, -fx, -fy, -fz, rax, ray, raz, -lx, -ly, -lz, nax, nay, naz, inv_m, ixx_inv, dinv)
        _push(v, w, b, fx, fy, fz, rbx, rby, rbz, lx, ly, lz, nbx, nby, nbz, inv_m, ixx_inv, dinv)
    return bend_max


@numba.njit(cache=CACHE, inline="always")
def _active_corners(x, ax, hh, s_th, c_th, th_dot, xp_dot, kc, inv_m, ixx_inv, dinv, ctile, cdat, cimp):
    """Stage 3, every step: the tile corners below the plate (geometry frozen for the step), visited
    corner-major so that consecutive Gauss-Seidel updates touch different tiles. Fills per active corner its
    tile, lever arm r, spring force k a^2.2, plate surface velocity u, 1/m_eff along the normal and the
    tangential corner velocity per unit normal impulse; zeroes its impulse. Returns the number of active
    corners."""
    pnx = 0.0
    pny = -s_th
    pnz = c_th
    n_act = 0
    for cnr in range(4):
        for i in range(x.shape[0]):
            sa = hh if (cnr == 0 or cnr == 3) else -hh
            sb = hh if cnr < 2 else -hh
            rx = sa * ax[i, 0] + sb * ax[i, 3]
            ry = sa * ax[i, 1] + sb * ax[i, 4]
            rz = sa * ax[i, 2] + sb * ax[i, 5]
            py = x[i, 1] + ry
            pz = x[i, 2] + rz
            wc = -py * s_th + pz * c_th
            if wc >= 0.0:
                continue
            ctile[n_act] = i
            cdat[n_act, 0] = rx
            cdat[n_act, 1] = ry
            cdat[n_act, 2] = rz
            cdat[n_act, 3] = spring_force(-wc, kc)
            cdat[n_act, 4] = xp_dot
            cdat[n_act, 5] = -th_dot * pz
            cdat[n_act, 6] = th_dot * py
            # step-constant response of the corner to a normal impulse: I^-1 (r x n), 1/m_eff, and the
            # tangential corner velocity per unit normal impulse (geometry is frozen for the step)
            nx, ny, nz = ax[i, 6], ax[i, 7], ax[i, 8]
            cx = ry * pnz - rz * pny
            cy = rz * pnx - rx * pnz
            cz = rx * pny - ry * pnx
            ix, iy, iz = _apply_inv_inertia(nx, ny, nz, ixx_inv, dinv, cx, cy, cz)
            cdat[n_act, 7] = inv_m + cx * ix + cy * iy + cz * iz
            gx = iy * rz - iz * ry
            gy = iz * rx - ix * rz
            gz = ix * ry - iy * rx
            dvn = gx * pnx + gy * pny + gz * pnz
            cdat[n_act, 8] = gx - dvn * pnx
            cdat[n_act, 9] = gy - dvn * pny
            cdat[n_act, 10] = gz - dvn * pnz
            cimp[n_act, 0] = 0.0
            cimp[n_act, 1] = 0.0
            cimp[n_act, 2] = 0.0
            n_act += 1
    return n_act


@numba.njit(cache=CACHE, inline="always")
def _contact_pass(n_act, ctile, cdat, cimp, v, w, ax, s_th, c_th, dt, cc, mus, muk, vt, inv_m, ixx_inv, dinv):
    """Stage 4a, one Gauss-Seidel sweep over the active corners: each corner's impulse is taken off its tile and
    re-evaluated with the shared contact law (implicit normal damper, Coulomb stick/slip), then applied again."""
    pnx = 0.0
    pny = -s_th
    pnz = c_th
    for k in range(n_act):
        i = ctile[k]
        nx, ny, nz = ax[i, 6], ax[i, 7], ax[i, 8]
        rx, ry, rz = cdat[k, 0], cdat[k, 1], cdat[k, 2]
        ux, uy, uz = cdat[k, 4], cdat[k, 5], cdat[k, 6]
        # remove this corner's accumulated impulse from its tile
        _push(v, w, i, -cimp[k, 0], -cimp[k, 1], -cimp[k, 2], rx, ry, rz, 0.0, 0.0, 0.0, nx, ny, nz, inv_m,
              ixx_inv, dinv)
        vrx = v[i, 0] + w[i, 1] * rz - w[i, 2] * ry - ux
        vry = v[i, 1] + w[i, 2] * rx - w[i, 0] * rz - uy
        vrz = v[i, 2] + w[i, 0] * ry - w[i, 1] * rx - uz
        vn = vrx * pnx + vry * pny + vrz * pnz
        kn_inv = cdat[k, 7]
        fn = damped_normal_force(cdat[k, 3], vn, cc, kn_inv, dt)
        jx = 0.0
        jy = 0.0
        jz = 0.0
        if fn > 0.0:
            pn = dt * fn
            # tangential slip after the normal impulse (its rotational part moves the corner too)
            tx = vrx - vn * pnx + pn * cdat[k, 8]
            ty = vry - vn * pny + pn * cdat[k, 9]
            tz = vrz - vn * pnz + pn * cdat[k, 10]
            slip = math.sqrt(tx * tx + ty * ty + tz * tz)
            jx = pn * pnx
            jy = pn * pny
            jz = pn * pnz
            if slip > 0.0:
                ex, ey, ez = tx / slip, ty / slip, tz / slip
                cx2 = ry * ez - rz * ey
                cy2 = rz * ex - rx * ez
                cz2 = rx * ey - ry * ex
                jx2, jy2, jz2 = _apply_inv_inertia(nx, ny, nz, ixx_inv, dinv, cx2, cy2, cz2)
                kt_inv = inv_m + cx2 * jx2 + cy2 * jy2 + cz2 * jz2
                sc = friction_scale(slip, fn, mus, muk, vt, kt_inv, dt)
                pt = (1.0 - sc) * slip / kt_inv
                jx -= pt * ex
                jy -= pt * ey
                jz -= pt * ez
        cimp[k, 0] = jx
        cimp[k, 1] = jy
        cimp[k, 2] = jz
        _push(v, w, i, jx, jy, jz, rx, ry, rz, 0.0, 0.0, 0.0, nx, ny, nz, inv_m, ixx_inv, dinv)


@numba.njit(cache=CACHE, inline="always")
def _joint_pass(it, links, jra, jrb, jfr, jkt, jkr, jb, gam, pacc, v, w, ax, inv_m, ixx_inv, dinv):
    """Stage 4b, one block Gauss-Seidel sweep over the joints (direction alternating with ``it`` to avoid an
    ordering bias): the 3 translation rows solved together, then the 2 rotation rows with the updated angular
    velocities; each row a backward-Euler spring-damper ``J v' + k C / (dt k + c) + P / (dt (dt k + c)) = 0``."""
    nj = links.shape[0]
    for jj in range(nj):
        j = jj if it % 2 == 0 else nj - 1 - jj
        a = links[j, 0]
        b = links[j, 1]
        rax, ray, raz = jra[j, 0], jra[j, 1], jra[j, 2]
        rbx, rby, rbz = jrb[j, 0], jrb[j, 1], jrb[j, 2]
        t1x, t1y, t1z = jfr[j, 0], jfr[j, 1], jfr[j, 2]
        t2x, t2y, t2z = jfr[j, 3], jfr[j, 4], jfr[j, 5]
        nnx, nny, nnz = jfr[j, 6], jfr[j, 7], jfr[j, 8]
        nax, nay, naz = ax[a, 6], ax[a, 7], ax[a, 8]
        nbx, nby, nbz = ax[b, 6], ax[b, 7], ax[b, 8]
        # translation rows
        dvx = v[b, 0] + w[b, 1] * rbz - w[b, 2] * rby - v[a, 0] - w[a, 1] * raz + w[a, 2] * ray
        dvy = v[b, 1] + w[b, 2] * rbx - w[b, 0] * rbz - v[a, 1] - w[a, 2] * rax + w[a, 0] * raz
        dvz = v[b, 2] + w[b, 0] * rby - w[b, 1] * rbx - v[a, 2] - w[a, 0] * ray + w[a, 1] * rax
        e0_ = dvx * t1x + dvy * t1y + dvz * t1z + jb[j, 0] + gam[0] * pacc[j, 0]
        e1_ = dvx * t2x + dvy * t2y + dvz * t2z + jb[j, 1] + gam[1] * pacc[j, 1]
        e2_ = dvx * nnx + dvy * nny + dvz * nnz + jb[j, 2] + gam[2] * pacc[j, 2]
        d0 = -(jkt[j, 0] * e0_ + jkt[j, 1] * e1_ + jkt[j, 2] * e2_)
        d1 = -(jkt[j, 1] * e0_ + jkt[j, 3] * e1_ + jkt[j, 4] * e2_)
        d2 = -(jkt[j, 2] * e0_ + jkt[j, 4] * e1_ + jkt[j, 5] * e2_)
        pacc[j, 0] += d0
        pacc[j, 1] += d1
        pacc[j, 2] += d2
        # rotation rows (use angular velocities after the translation update below)
        fx = d0 * t1x + d1 * t2x + d2 * nnx
        fy = d0 * t1y + d1 * t2y + d2 * nny
        fz = d0 * t1z + d1 * t2z + d2 * nnz
        _push(v, w, a, -fx, -fy, -fz, rax, ray, raz, 0.0, 0.0, 0.0, nax, nay, naz, inv_m, ixx_inv, dinv)
        _push(v, w, b, fx, fy, fz, rbx, rby, rbz, 0.0, 0.0, 0.0, nbx, nby, nbz, inv_m, ixx_inv, dinv)
        dwx = w[b, 0] - w[a, 0]
        dwy = w[b, 1] - w[a, 1]
        dwz = w[b, 2] - w[a, 2]
        e3_ = dwx * t2x + dwy * t2y + dwz * t2z + jb[j, 3] + gam[3] * pacc[j, 3]
        e4_ = dwx * nnx + dwy * nny + dwz * nnz + jb[j, 4] + gam[4] * pacc[j, 4]
        d3 = -(jkr[j, 0] * e3_ + jkr[j, 1] * e4_)
        d4 = -(jkr[j, 1] * e3_ + jkr[j, 2] * e4_)
        pacc[j, 3] += d3
        pacc[j, 4] += d4
        lx = d3 * t2x + d4 * nnx
        ly = d3 * t2y + d4 * nny
        lz = d3 * t2z + d4 * nnz
        _turn(w, a, -lx, -ly, -lz, nax, nay, naz, ixx_inv, dinv)
        _turn(w, b, lx, ly, lz, nbx, nby, nbz, ixx_inv, dinv)


@numba.njit(cache=CACHE, inline="always")
def _plate_work(n_act, cimp, cdat, work, work_abs):
    """The plate's work on the disc through this step's contact impulses (impulse . plate surface velocity), J,
    added to the running total and to the running total of its absolute values."""
    for k in range(n_act):
        dw_ = cimp[k, 0] * cdat[k, 4] + cimp[k, 1] * cdat[k, 5] + cimp[k, 2] * cdat[k, 6]
        work += dw_
        work_abs += abs(dw_)
    return work, work_abs


@numba.njit(cache=CACHE, inline="always")
def _integrate(x, v, q, w, dt):
    """Stage 5: positions and unit quaternions advance with the new velocities and angular velocities."""
    for i in range(x.shape[0]):
        x[i, 0] += dt * v[i, 0]
        x[i, 1] += dt * v[i, 1]
        x[i, 2] += dt * v[i, 2]
        qw, qx, qy, qz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        wx, wy, wz = 0.5 * dt * w[i, 0], 0.5 * dt * w[i, 1], 0.5 * dt * w[i, 2]
        nw_ = qw - wx * qx - wy * qy - wz * qz
        nx_ = qx + wx * qw + wy * qz - wz * qy
        ny_ = qy + wy * qw + wz * qx - wx * qz
        nz_ = qz + wz * qw + wx * qy - wy * qx
        ln = 1.0 / math.sqrt(nw_ * nw_ + nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
        q[i, 0] = nw_ * ln
        q[i, 1] = nx_ * ln
        q[i, 2] = ny_ * ln
        q[i, 3] = nz_ * ln


@numba.njit(cache=CACHE, fastmath=FAST)
def rigid_probe(prm, rest, links, link_dir, cells, yaw_out, cu_out, cv_out, diag):
    """Simulate one rigid-tile probe; fills the traces and ``diag`` and returns (status, records written).

    ``diag``: [max (E - E0 - W_plate) in J, max |bending angle| in rad, plate work W in J, final E - E0 in J].
    The stages (module docstring) are inlined functions, so this is one compiled loop.
    """
    n = rest.shape[0]
    nj = links.shape[0]
    inv_m = 1.0 / prm[P_MASS]
    dt = prm[P_DT]
    ixx = prm[R_IXX]
    izz = prm[R_IZZ]
    ixx_inv = 1.0 / ixx
    dinv = 1.0 / izz - 1.0 / ixx
    n_iter = int(prm[R_NITER])
    n_steps = int(prm[P_NSTEPS])
    rec_every = int(prm[P_RECEVERY])
    block_refresh = int(prm[R_REFRESH])
    kc = prm[P_KC] * prm[R_CORNERW]
    cc = prm[P_CC] * prm[R_CORNERW]
    hh = 0.5 * prm[R_H]
    rk, gam, kfac = _row_constants(prm, dt)

    x = np.empty((n, 3))
    v = np.zeros((n, 3))
    q = np.zeros((n, 4))
    w = np.zeros((n, 3))
    ax = np.empty((n, 9))  # tile axes in world: e1 (0:3), e2 (3:6), normal (6:9)
    # per-joint data of the current step
    jra = np.empty((nj, 3))
    jrb = np.empty((nj, 3))
    jfr = np.empty((nj, 9))  # t1, t2, n
    jkt = np.empty((nj, 6))  # inverse of the 3x3 translation block (xx, xy, xz, yy, yz, zz)
    jkr = np.empty((nj, 3))  # inverse of the 2x2 rotation block
    jb = np.empty((nj, 5))  # bias k C / (dt k + c)
    jc = np.zeros((nj, 5))  # position errors C
    pacc = np.zeros((nj, 5))  # accumulated impulses (warm start)
    ctile = np.empty(4 * n, dtype=np.int64)  # active corner contacts: tile index
    cdat = np.empty((4 * n, 11))  # lever arm r (3), spring force k a^2.2, plate velocity u (3), 1/m_n, dv_t/dp_n (3)
    cimp = np.empty((4 * n, 3))  # accumulated contact impulse in this step
    _place_tiles(prm, rest, x, q)
    yaw = prm[P_YAW0]
    n_rec = 0
    status = Status.OK
    work = 0.0
    work_abs = 0.0
    e0 = 0.0
    excess_max = -1e300
    bend_max = 0.0
    e_last = 0.0
    for step in range(n_steps + 1):
        th, th_dot, xp, xp_dot = plate_state(step * dt, prm[P_FREQ], prm[P_AMP], prm[P_BP], prm[P_RAMP])
        s_th = math.sin(th)
        c_th = math.cos(th)
        _tile_axes(q, ax)
        if step % rec_every == 0:
            status, yaw, n_rec, e0, excess_max, e_last = _check_and_record(
                step, prm, x, v, w, ax, jc, rk, rest, cells, xp, s_th, c_th, yaw, e0, work, work_abs, excess_max,
                bend_max, yaw_out, cu_out, cv_out, n_rec)
            if status != Status.OK:
                break
        if step == n_steps:
            break
        _gravity_and_gyroscopic(v, w, ax, dt, prm[P_G], ixx, izz, ixx_inv, dinv)
        refresh = step == 0 or (block_refresh > 0 and step % block_refresh == 0)
        bend_max = _joint_setup(refresh, x, v, w, ax, links, link_dir, hh, inv_m, ixx_inv, dinv, gam, kfac, jra,
                                jrb, jfr, jkt, jkr, jb, jc, pacc, bend_max)
        n_act = _active_corners(x, ax, hh, s_th, c_th, th_dot, xp_dot, kc, inv_m, ixx_inv, dinv, ctile, cdat, cimp)
        for it in range(n_iter):
            _contact_pass(n_act, ctile, cdat, cimp, v, w, ax, s_th, c_th, dt, cc, prm[P_MUS], prm[P_MUK], prm[P_VT],
                          inv_m, ixx_inv, dinv)
            _joint_pass(it, links, jra, jrb, jfr, jkt, jkr, jb, gam, pacc, v, w, ax, inv_m, ixx_inv, dinv)
        work, work_abs = _plate_work(n_act, cimp, cdat, work, work_abs)
        _integrate(x, v, q, w, dt)
    diag[0] = excess_max
    diag[1] = bend_max
    diag[2] = work
    diag[3] = e_last
    return status, n_rec


@numba.njit(cache=CACHE, parallel=True)
def rigid_batch_parallel(prm, rest, links, link_dir, cells, yaw_out, cu_out, cv_out, diag, status_out, nrec_out):
    """Run a batch of probes over threads (one probe per iteration)."""
    for b in numba.prange(prm.shape[0]):
        s, r = rigid_probe(prm[b], rest[b], links, link_dir, cells, yaw_out[b], cu_out[b], cv_out[b], diag[b])
        status_out[b] = s
        nrec_out[b] = r


@numba.njit(cache=CACHE)
def rigid_batch_serial(prm, rest, links, link_dir, cells, yaw_out, cu_out, cv_out, diag, status_out, nrec_out):
    """The same batch on the calling thread (no threading overhead for single probes)."""
    for b in range(prm.shape[0]):
        s, r = rigid_probe(prm[b], rest[b], links, link_dir, cells, yaw_out[b], cu_out[b], cv_out[b], diag[b])
        status_out[b] = s
        nrec_out[b] = r


@lru_cache(maxsize=256)
def _params(obj, config: RigidTileConfig) -> RigidTileParams:
    return build_params(obj, config)


def param_vector(spec: ProbeSpec, dt: float, slip_limit: float, config: RigidTileConfig | None = None,
                 law: ContactLaw = PAPER_CONTACT, record_interval_s: float = DEFAULT_RECORD_INTERVAL_S) -> np.ndarray:
    """The rigid kernel's parameter vector (``N_RIGID_PARAMS``) for one probe; SI units."""
    config = config or RigidTileConfig()
    p = _params(spec.obj, config)
    prm = common_vector(spec, dt, slip_limit, p.tile_mass, N_RIGID_PARAMS, contact_weight=0.25, law=law,
                        record_interval_s=record_interval_s)
    prm[P_KB] = p.k_bending
    prm[P_KIN] = p.row_k[0]
    prm[P_CIN] = p.row_c[0]
    prm[R_H] = p.tile_size
    prm[R_IXX] = p.inertia_xx
    prm[R_IZZ] = p.inertia_zz
    prm[R_CB] = p.row_c[3]
    prm[R_KT2] = p.row_k[1]
    prm[R_CT2] = p.row_c[1]
    prm[R_KN] = p.row_k[2]
    prm[R_CN] = p.row_c[2]
    prm[R_KRN] = p.row_k[4]
    prm[R_CRN] = p.row_c[4]
    prm[R_NITER] = config.iterations
    prm[R_FOLD] = config.fold_angle
    prm[R_FOLDW] = config.fold_tile_w
    prm[R_EREL] = config.energy_rel_tol
    prm[R_EABS] = config.energy_abs_tol
    prm[R_CORNERW] = 0.25
    prm[R_REFRESH] = config.block_refresh
    return prm


def run_rigid_param_arrays(prm: np.ndarray, rest: np.ndarray, geom, parallel: bool | None = None
                           ) -> dict[str, np.ndarray]:
    """Run the rigid kernel on prepared arrays (exposed for tests that inject bad parameters)."""
    out = allocate_outputs(prm)
    yaw, cu, cv, status, nrec = out["yaw"], out["cu"], out["cv"], out["status"], out["nrec"]
    diag = np.zeros((len(prm), 4))
    if parallel is None:
        parallel = len(prm) > 1
    kernel = rigid_batch_parallel if parallel else rigid_batch_serial
    order = joint_order(geom)
    links, link_dir = geom.links[order], geom.link_dir[order]
    load_first(rigid_probe, prm[0], rest[0], links, link_dir, geom.cells, yaw[0], cu[0], cv[0], diag[0])
    kernel(prm, rest, links, link_dir, geom.cells, yaw, cu, cv, diag, status, nrec)
    out["diag"] = diag
    return out


def run_rigid_arrays(probes: Sequence[ProbeSpec], dt: float = DEFAULT_DT["rigid"], slip_limit: float = SLIP_LIMIT_M,
                     config: RigidTileConfig | None = None, parallel: bool | None = None,
                     law: ContactLaw = PAPER_CONTACT, record_interval_s: float = DEFAULT_RECORD_INTERVAL_S
                     ) -> dict[str, np.ndarray]:
    """Run a batch of probes with the rigid-tile model.

    Returns the keys of ``TileLinkPhysics.run_param_arrays`` ("prm" with ``P_NSTEPS``/``P_RECEVERY`` filled,
    "yaw" rad, "cu"/"cv" m traces every ``record_interval_s``, "status" codes of
    :class:`~plate_env.core.probe.Status`, "nrec") plus "diag" (B, 4):
    max energy excess over the plate's work (J), max |bending angle| (rad), plate work (J), final E - E0 (J),
    and "wall_s", the kernel's wall time.
    """
    config = config or RigidTileConfig()
    probes = list(probes)
    prm = np.stack([param_vector(s, dt, slip_limit, config, law, record_interval_s) for s in probes])
    geom = _params(probes[0].obj, config).geom
    rest = np.stack([_params(s.obj, config).geom.rest for s in probes])
    t0 = time.perf_counter()
    out = run_rigid_param_arrays(prm, rest, geom, parallel)
    out["wall_s"] = np.array(time.perf_counter() - t0)
    return out
