"""numba kernel of the modal (floating-frame) rigid-tile disc, :mod:`plate_env.physics.tilelink.rigid_modal`
(issue 34; experimental, not a registered backend model).

One step of ``dt`` s (semi-implicit, like the rigid-tile kernel):

1. the elastic forces of the modes: linear ``-w^2 q`` and the condensed joint stiffening ``-d/dq (q^T B s +
   s^T H s / 2)``; each mode's spring-damper is integrated by backward Euler, so its response to an impulse is
   scaled by ``1 / (1 + dt c + dt^2 w^2)`` (the modal "mass" of the step); gravity and the gyroscopic torque act
   on the frame;
2. the tiles' centres (frame + modal displacement + the static foreshortening ``U s``) and axes (frame x
   the tile's modal rotation) are built;
3. plate contact at every tile corner below the plate, the shared law (:func:`contact.spring_force`,
   :func:`contact.damped_normal_force`, :func:`contact.friction_scale`) with a quarter of the tile's
   coefficients, ``iterations`` Gauss-Seidel sweeps; a corner's impulse moves the frame (translation and rotation)
   and the modes through the corner's mode shapes ``psi_k = phi_t,k + phi_r,k x c`` (``c`` its offset on the
   tile);
4. frame position/quaternion and modal coordinates advance with the new velocities.

Records (~1 ms): the tile-link observation and checks (:func:`kernels.record`), FOLDED when a tile turns over.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from functools import lru_cache

import numba
import numpy as np

from plate_env.core.probe import SLIP_LIMIT_M, ProbeResult, ProbeSpec, Status, check_probes
from plate_env.physics.tilelink import params
from plate_env.physics.tilelink.contact import PAPER_CONTACT, ContactLaw
from plate_env.physics.tilelink.jit_cache import CACHE
from plate_env.physics.tilelink.kernels import (
    FAST,
    damped_normal_force,
    friction_scale,
    load_first,
    plate_at,
    record,
    spring_force,
)
from plate_env.physics.tilelink.params import DEFAULT_RECORD_INTERVAL_S, N_PARAMS, allocate_outputs, common_vector
from plate_env.physics.tilelink.rigid_modal import (
    DEFAULT_MODAL,
    ModalDiscConfig,
    build_modal_params,
    modal_propagator,
)

(M_H, M_IB0, M_IB1, M_IB2, M_NITER, M_FOLDW, M_FS, M_EXACT) = range(N_PARAMS, N_PARAMS + 8)
N_MODAL_PARAMS = N_PARAMS + 8
#: The modal integrators (``M_EXACT`` = bit flags): backward Euler (0, :func:`modal_probe`), or the exact propagator
#: (:func:`rigid_modal.modal_propagator`, bit 1, :func:`modal_probe_exact`) with the stiffening held at its start
#: value over the step and the contact impulse moving the modes' displacement as a force held over the step, or (bit
#: 4) as the frame's symplectic-Euler kick does (``dq = dt dv``). (A predictor-corrector of the stiffening, bit 2,
#: was measured at 7790646 and removed: rigid_modal_notes.md.) The exact integrator is a separate probe function:
#: a runtime switch inside the backward-Euler loop cost that loop ~30 % (numba/LLVM), measured.
INTEGRATORS = {"backward_euler": 0, "exact": 1, "exact_kick": 5}


@numba.njit(cache=CACHE, inline="always")
def _quat_matrix(qw, qx, qy, qz, rm):
    rm[0, 0] = 1.0 - 2.0 * (qy * qy + qz * qz)
    rm[0, 1] = 2.0 * (qx * qy - qw * qz)
    rm[0, 2] = 2.0 * (qx * qz + qw * qy)
    rm[1, 0] = 2.0 * (qx * qy + qw * qz)
    rm[1, 1] = 1.0 - 2.0 * (qx * qx + qz * qz)
    rm[1, 2] = 2.0 * (qy * qz - qw * qx)
    rm[2, 0] = 2.0 * (qx * qz - qw * qy)
    rm[2, 1] = 2.0 * (qy * qz + qw * qx)
    rm[2, 2] = 1.0 - 2.0 * (qx * qx + qy * qy)


@numba.njit(cache=CACHE, inline="always")
def _rodrigues(tx, ty, tz, out):
    ang = math.sqrt(tx * tx + ty * ty + tz * tz)
    if ang < 1e-12:
        sa = 1.0
        ca = 0.5
    else:
        sa = math.sin(ang) / ang
        ca = (1.0 - math.cos(ang)) / (ang * ang)
    out[0, 0] = 1.0 - ca * (ty * ty + tz * tz)
    out[0, 1] = -sa * tz + ca * tx * ty
    out[0, 2] = sa * ty + ca * tx * tz
    out[1, 0] = sa * tz + ca * tx * ty
    out[1, 1] = 1.0 - ca * (tx * tx + tz * tz)
    out[1, 2] = -sa * tx + ca * ty * tz
    out[2, 0] = -sa * ty + ca * tx * tz
    out[2, 1] = sa * tx + ca * ty * tz
    out[2, 2] = 1.0 - ca * (tx * tx + ty * ty)


@numba.njit(cache=CACHE, inline="always")
def _tile_mobility(rx, ry, rz, inv_mt, iw, rm, a_body, wm, sk_, g1, tmp):
    """The 6x6 world mobility ``wm`` of one tile: its (velocity, angular velocity) change per (force, torque)
    impulse at its centre, through the frame (lever ``r`` from the frame origin, inverse inertia ``iw``) and the
    modes (``a_body``: the tile's modal self-mobility ``sum_k s_k phi_k phi_k^T`` in the body frame, rotated by
    ``rm``). ``sk_``, ``g1`` (3, 3) and ``tmp`` (6, 6) are scratch."""
    sk_[0, 0], sk_[0, 1], sk_[0, 2] = 0.0, -rz, ry
    sk_[1, 0], sk_[1, 1], sk_[1, 2] = rz, 0.0, -rx
    sk_[2, 0], sk_[2, 1], sk_[2, 2] = -ry, rx, 0.0
    for r_ in range(3):
        for c_ in range(3):
            g1[r_, c_] = iw[r_, 0] * sk_[0, c_] + iw[r_, 1] * sk_[1, c_] + iw[r_, 2] * sk_[2, c_]
    for r_ in range(3):
        for c_ in range(3):
            wm[r_, c_] = -(sk_[r_, 0] * g1[0, c_] + sk_[r_, 1] * g1[1, c_] + sk_[r_, 2] * g1[2, c_])
            wm[r_, 3 + c_] = -(sk_[r_, 0] * iw[0, c_] + sk_[r_, 1] * iw[1, c_] + sk_[r_, 2] * iw[2, c_])
            wm[3 + r_, c_] = g1[r_, c_]
            wm[3 + r_, 3 + c_] = iw[r_, c_]
        wm[r_, r_] += inv_mt
    # modal part: blockdiag(R, R) A blockdiag(R, R)^T
    for r_ in range(6):
        ro = 3 * (r_ // 3)
        rr = r_ % 3
        for c_ in range(6):
            tmp[r_, c_] = (rm[rr, 0] * a_body[ro, c_] + rm[rr, 1] * a_body[ro + 1, c_]
                           + rm[rr, 2] * a_body[ro + 2, c_])
    for r_ in range(6):
        for c_ in range(6):
            co = 3 * (c_ // 3)
            cc_ = c_ % 3
            wm[r_, c_] += tmp[r_, co] * rm[cc_, 0] + tmp[r_, co + 1] * rm[cc_, 1] + tmp[r_, co + 2] * rm[cc_, 2]


@numba.njit(cache=CACHE, inline="always")
def _apply_local(wm, cx, cy, cz, jx, jy, jz, lv, dwr):
    """Impulse ``j`` at offset ``c`` from the tile centre: the tile's local velocities ``lv`` change by the
    mobility ``wm`` times the wrench (j, c x j), which is added to ``dwr``."""
    lx = cy * jz - cz * jy
    ly = cz * jx - cx * jz
    lz = cx * jy - cy * jx
    for r_ in range(6):
        lv[r_] += (wm[r_, 0] * jx + wm[r_, 1] * jy + wm[r_, 2] * jz + wm[r_, 3] * lx + wm[r_, 4] * ly
                   + wm[r_, 5] * lz)
    dwr[0] += jx
    dwr[1] += jy
    dwr[2] += jz
    dwr[3] += lx
    dwr[4] += ly
    dwr[5] += lz


@numba.njit(cache=CACHE, inline="always")
def _inv_mass_along(wm, cx, cy, cz, ex, ey, ez):
    """Inverse effective mass of a tile point at offset ``c`` along the unit direction ``e``: ``e . du`` for a
    unit impulse ``e`` there."""
    lx = cy * ez - cz * ey
    ly = cz * ex - cx * ez
    lz = cx * ey - cy * ex
    # e . dv + (c x e) . dw = w6^T wm w6 with w6 = (e, c x e)
    acc = 0.0
    for r_ in range(6):
        wr = ex if r_ == 0 else ey if r_ == 1 else ez if r_ == 2 else lx if r_ == 3 else ly if r_ == 4 else lz
        acc += wr * (wm[r_, 0] * ex + wm[r_, 1] * ey + wm[r_, 2] * ez + wm[r_, 3] * lx + wm[r_, 4] * ly
                     + wm[r_, 5] * lz)
    return acc
@numba.njit(cache=CACHE, inline="always")
def _self_mobility(pt, pr, sk, amob):
    """Each tile's modal self-mobility (body frame) ``sum_k s_k phi_k phi_k^T`` over its 6 dofs into ``amob``."""
    n = pt.shape[0]
    nk = sk.shape[0]
    for i in range(n):
        for k in range(nk):
            for r_ in range(6):
                vr_ = pt[i, r_, k] if r_ < 3 else pr[i, r_ - 3, k]
                for c_ in range(6):
                    vc_ = pt[i, c_, k] if c_ < 3 else pr[i, c_ - 3, k]
                    amob[i, r_, c_] += sk[k] * vr_ * vc_


@numba.njit(cache=CACHE, inline="always")
def _tile_geometry(q, s, pairs, rest, pt, pr, us, fs, xf, rm, trot, x, s_th, c_th):
    """Stage 2: the products ``s``, each tile's rotation in the body frame (``trot``) and world centre (``x``,
    with the foreshortening ``U s`` when ``fs``). Returns the lowest plate-normal component of a tile normal."""
    n = rest.shape[0]
    nk = q.shape[0]
    npair = pairs.shape[0]
    for p in range(npair):
        s[p] = q[pairs[p, 0]] * q[pairs[p, 1]]
    tile_w_min = 1.0
    for i in range(n):
        bx = rest[i, 0]
        by = rest[i, 1]
        bz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        for k in range(nk):
            qk = q[k]
            bx += pt[i, 0, k] * qk
            by += pt[i, 1, k] * qk
            bz += pt[i, 2, k] * qk
            tx += pr[i, 0, k] * qk
            ty += pr[i, 1, k] * qk
            tz += pr[i, 2, k] * qk
        if fs:
            for p in range(npair):
                bx += us[i, 0, p] * s[p]
                by += us[i, 1, p] * s[p]
                bz += us[i, 2, p] * s[p]
        _rodrigues(tx, ty, tz, trot[i])
        for d in range(3):
            x[i, d] = xf[d] + rm[d, 0] * bx + rm[d, 1] * by + rm[d, 2] * bz
        # world tile normal's plate-normal component
        nz_b0, nz_b1, nz_b2 = trot[i, 0, 2], trot[i, 1, 2], trot[i, 2, 2]
        nwy = rm[1, 0] * nz_b0 + rm[1, 1] * nz_b1 + rm[1, 2] * nz_b2
        nwz = rm[2, 0] * nz_b0 + rm[2, 1] * nz_b1 + rm[2, 2] * nz_b2
        tw = -nwy * s_th + nwz * c_th
        if tw < tile_w_min:
            tile_w_min = tw
    return tile_w_min


@numba.njit(cache=CACHE, inline="always")
def _max_speed(x, xf, vf, wf, rm, pt, qd):
    """The largest squared tile-centre speed (m^2/s^2; the foreshortening's velocity left out)."""
    n = x.shape[0]
    nk = qd.shape[0]
    vmax2 = 0.0
    for i in range(n):
        rx = x[i, 0] - xf[0]
        ry = x[i, 1] - xf[1]
        rz = x[i, 2] - xf[2]
        ux = 0.0
        uy = 0.0
        uz = 0.0
        for k in range(nk):
            ux += pt[i, 0, k] * qd[k]
            uy += pt[i, 1, k] * qd[k]
            uz += pt[i, 2, k] * qd[k]
        vx = vf[0] + wf[1] * rz - wf[2] * ry + rm[0, 0] * ux + rm[0, 1] * uy + rm[0, 2] * uz
        vy = vf[1] + wf[2] * rx - wf[0] * rz + rm[1, 0] * ux + rm[1, 1] * uy + rm[1, 2] * uz
        vz = vf[2] + wf[0] * ry - wf[1] * rx + rm[2, 0] * ux + rm[2, 1] * uy + rm[2, 2] * uz
        sp = vx * vx + vy * vy + vz * vz
        if not (sp <= vmax2):
            vmax2 = sp
    return vmax2


@numba.njit(cache=CACHE, inline="always")
def _modal_forces(q, qd, s, pairs, bc, hq, omega, sk, force, tmp_p, dt):
    """Stage 1: the modes' elastic forces and their backward-Euler spring-damper velocity update."""
    nk = q.shape[0]
    npair = pairs.shape[0]
    for k in range(nk):
        acc = 0.0
        for p in range(npair):
            acc += bc[k, p] * s[p]
        force[k] = -acc
    # v = B^T q + H s, acting through ds/dq
    for p in range(npair):
        acc = 0.0
        for k in range(nk):
            acc += bc[k, p] * q[k]
        for p2 in range(npair):
            acc += hq[p, p2] * s[p2]
        tmp_p[p] = acc
    for p in range(npair):
        a = pairs[p, 0]
        b = pairs[p, 1]
        force[a] -= tmp_p[p] * q[b]
        force[b] -= tmp_p[p] * q[a]
    for k in range(nk):
        qd[k] = sk[k] * (qd[k] + dt * (force[k] - omega[k] * omega[k] * q[k]))


@numba.njit(cache=CACHE, inline="always")
def _frame_forces(vf, wf, rm, iw, dt, grav, ib0, ib1, ib2):
    """Stage 1 for the frame: gravity, the world inverse inertia ``iw``, the gyroscopic torque."""
    vf[2] -= dt * grav
    for r_ in range(3):
        for c_ in range(3):
            iw[r_, c_] = (rm[r_, 0] * rm[c_, 0] / ib0 + rm[r_, 1] * rm[c_, 1] / ib1
                          + rm[r_, 2] * rm[c_, 2] / ib2)
    # L = I w in body: w_b = R^T w
    wbx = rm[0, 0] * wf[0] + rm[1, 0] * wf[1] + rm[2, 0] * wf[2]
    wby = rm[0, 1] * wf[0] + rm[1, 1] * wf[1] + rm[2, 1] * wf[2]
    wbz = rm[0, 2] * wf[0] + rm[1, 2] * wf[1] + rm[2, 2] * wf[2]
    gx = -(wby * ib2 * wbz - wbz * ib1 * wby)
    gy = -(wbz * ib0 * wbx - wbx * ib2 * wbz)
    gz = -(wbx * ib1 * wby - wby * ib0 * wbx)
    wbx += dt * gx / ib0
    wby += dt * gy / ib1
    wbz += dt * gz / ib2
    for d in range(3):
        wf[d] = rm[d, 0] * wbx + rm[d, 1] * wby + rm[d, 2] * wbz


@numba.njit(cache=CACHE, inline="always")
def _active_tiles(hh, trot, rm, x, xf, s_th, c_th, th_dot, xp_dot, kc, cdat, cimp, tfirst, tlast, ttile,
                  inv_mt, iw, amob, wmob, sc3a, sc3b, sc6):
    """Stage 3a: the corners below the plate grouped by tile, each tile's 6x6 mobility. Returns how many tiles."""
    n = x.shape[0]
    n_act = 0
    n_tact = 0
    for i in range(n):
        first = n_act
        for cnr in range(4):
            sa = hh if (cnr == 0 or cnr == 3) else -hh
            sb = hh if cnr < 2 else -hh
            cbx = sa * trot[i, 0, 0] + sb * trot[i, 0, 1]
            cby = sa * trot[i, 1, 0] + sb * trot[i, 1, 1]
            cbz = sa * trot[i, 2, 0] + sb * trot[i, 2, 1]
            cwx = rm[0, 0] * cbx + rm[0, 1] * cby + rm[0, 2] * cbz
            cwy = rm[1, 0] * cbx + rm[1, 1] * cby + rm[1, 2] * cbz
            cwz = rm[2, 0] * cbx + rm[2, 1] * cby + rm[2, 2] * cbz
            py = x[i, 1] + cwy
            pz = x[i, 2] + cwz
            wc = -py * s_th + pz * c_th
            if wc >= 0.0:
                continue
            cdat[n_act, 0] = cwx
            cdat[n_act, 1] = cwy
            cdat[n_act, 2] = cwz
            cdat[n_act, 3] = spring_force(-wc, kc)
            cdat[n_act, 4] = xp_dot
            cdat[n_act, 5] = -th_dot * pz
            cdat[n_act, 6] = th_dot * py
            cimp[n_act, 0] = 0.0
            cimp[n_act, 1] = 0.0
            cimp[n_act, 2] = 0.0
            n_act += 1
        if n_act == first:
            continue
        tfirst[n_tact] = first
        tlast[n_tact] = n_act
        ttile[n_tact] = i
        _tile_mobility(x[i, 0] - xf[0], x[i, 1] - xf[1], x[i, 2] - xf[2], inv_mt, iw, rm, amob[i], wmob[n_tact],
                       sc3a, sc3b, sc6)
        n_tact += 1
    return n_tact


@numba.njit(cache=CACHE, inline="always")
def _contact_sweeps(step, n_iter, n_tact, ttile, tfirst, tlast, wmob, x, xf, vf, wf, rm, iw, pt, pr, qd, sk,
                    cdat, cimp, lv, dwr, pnx, pny, pnz, cc, dt, mus, muk, vt, inv_mt):
    """Stage 3b: ``n_iter`` block Gauss-Seidel sweeps over the tiles in contact (module docstring)."""
    nk = qd.shape[0]
    # 3. block Gauss-Seidel over the tiles in contact: each tile's corners solved with its own mobility, the
    # tile's wrench change then pushed to the frame and the modes
    for _it in range(n_iter):
        for tt in range(n_tact):
            # the visiting order alternates from step to step (and sweep to sweep): a fixed order biases the
            # friction impulses of one sweep towards one side of the disc
            t = tt if (step + _it) % 2 == 0 else n_tact - 1 - tt
            i = ttile[t]
            wm = wmob[t]
            rx = x[i, 0] - xf[0]
            ry = x[i, 1] - xf[1]
            rz = x[i, 2] - xf[2]
            ubx = 0.0
            uby = 0.0
            ubz = 0.0
            obx = 0.0
            oby = 0.0
            obz = 0.0
            for k in range(nk):
                qk = qd[k]
                ubx += pt[i, 0, k] * qk
                uby += pt[i, 1, k] * qk
                ubz += pt[i, 2, k] * qk
                obx += pr[i, 0, k] * qk
                oby += pr[i, 1, k] * qk
                obz += pr[i, 2, k] * qk
            lv[0] = vf[0] + wf[1] * rz - wf[2] * ry + rm[0, 0] * ubx + rm[0, 1] * uby + rm[0, 2] * ubz
            lv[1] = vf[1] + wf[2] * rx - wf[0] * rz + rm[1, 0] * ubx + rm[1, 1] * uby + rm[1, 2] * ubz
            lv[2] = vf[2] + wf[0] * ry - wf[1] * rx + rm[2, 0] * ubx + rm[2, 1] * uby + rm[2, 2] * ubz
            lv[3] = wf[0] + rm[0, 0] * obx + rm[0, 1] * oby + rm[0, 2] * obz
            lv[4] = wf[1] + rm[1, 0] * obx + rm[1, 1] * oby + rm[1, 2] * obz
            lv[5] = wf[2] + rm[2, 0] * obx + rm[2, 1] * oby + rm[2, 2] * obz
            for d in range(6):
                dwr[d] = 0.0
            for c in range(tfirst[t], tlast[t]):
                cx, cy, cz = cdat[c, 0], cdat[c, 1], cdat[c, 2]
                _apply_local(wm, cx, cy, cz, -cimp[c, 0], -cimp[c, 1], -cimp[c, 2], lv, dwr)
                vrx = lv[0] + lv[4] * cz - lv[5] * cy - cdat[c, 4]
                vry = lv[1] + lv[5] * cx - lv[3] * cz - cdat[c, 5]
                vrz = lv[2] + lv[3] * cy - lv[4] * cx - cdat[c, 6]
                vn = vrx * pnx + vry * pny + vrz * pnz
                kn_inv = _inv_mass_along(wm, cx, cy, cz, pnx, pny, pnz)
                fn = damped_normal_force(cdat[c, 3], vn, cc, kn_inv, dt)
                jx = 0.0
                jy = 0.0
                jz = 0.0
                if fn > 0.0:
                    pn = dt * fn
                    jx = pn * pnx
                    jy = pn * pny
                    jz = pn * pnz
                    _apply_local(wm, cx, cy, cz, jx, jy, jz, lv, dwr)
                    vrx = lv[0] + lv[4] * cz - lv[5] * cy - cdat[c, 4]
                    vry = lv[1] + lv[5] * cx - lv[3] * cz - cdat[c, 5]
                    vrz = lv[2] + lv[3] * cy - lv[4] * cx - cdat[c, 6]
                    vn2 = vrx * pnx + vry * pny + vrz * pnz
                    tx = vrx - vn2 * pnx
                    ty = vry - vn2 * pny
                    tz = vrz - vn2 * pnz
                    slip = math.sqrt(tx * tx + ty * ty + tz * tz)
                    if slip > 0.0:
                        ex, ey, ez = tx / slip, ty / slip, tz / slip
                        kt_inv = _inv_mass_along(wm, cx, cy, cz, ex, ey, ez)
                        sc = friction_scale(slip, fn, mus, muk, vt, kt_inv, dt)
                        ptan = (1.0 - sc) * slip / kt_inv
                        _apply_local(wm, cx, cy, cz, -ptan * ex, -ptan * ey, -ptan * ez, lv, dwr)
                        jx -= ptan * ex
                        jy -= ptan * ey
                        jz -= ptan * ez
                cimp[c, 0] = jx
                cimp[c, 1] = jy
                cimp[c, 2] = jz
            # push the tile's wrench change (at its centre) to the frame and the modes
            fx, fy, fz, lx, ly, lz = dwr[0], dwr[1], dwr[2], dwr[3], dwr[4], dwr[5]
            vf[0] += fx * inv_mt
            vf[1] += fy * inv_mt
            vf[2] += fz * inv_mt
            ax_ = ry * fz - rz * fy + lx
            ay_ = rz * fx - rx * fz + ly
            az_ = rx * fy - ry * fx + lz
            wf[0] += iw[0, 0] * ax_ + iw[0, 1] * ay_ + iw[0, 2] * az_
            wf[1] += iw[1, 0] * ax_ + iw[1, 1] * ay_ + iw[1, 2] * az_
            wf[2] += iw[2, 0] * ax_ + iw[2, 1] * ay_ + iw[2, 2] * az_
            fbx = rm[0, 0] * fx + rm[1, 0] * fy + rm[2, 0] * fz
            fby = rm[0, 1] * fx + rm[1, 1] * fy + rm[2, 1] * fz
            fbz = rm[0, 2] * fx + rm[1, 2] * fy + rm[2, 2] * fz
            lbx = rm[0, 0] * lx + rm[1, 0] * ly + rm[2, 0] * lz
            lby = rm[0, 1] * lx + rm[1, 1] * ly + rm[2, 1] * lz
            lbz = rm[0, 2] * lx + rm[1, 2] * ly + rm[2, 2] * lz
            for k in range(nk):
                qd[k] += sk[k] * (pt[i, 0, k] * fbx + pt[i, 1, k] * fby + pt[i, 2, k] * fbz
                                  + pr[i, 0, k] * lbx + pr[i, 1, k] * lby + pr[i, 2, k] * lbz)


@numba.njit(cache=CACHE, inline="always")
def _advance(xf, vf, wf, q, qd, dt, qw, qx, qy, qz):
    """Stage 4: frame position and quaternion, modal coordinates. Returns the new quaternion."""
    nk = q.shape[0]
    for d in range(3):
        xf[d] += dt * vf[d]
    hx, hy, hz = 0.5 * dt * wf[0], 0.5 * dt * wf[1], 0.5 * dt * wf[2]
    nw_ = qw - hx * qx - hy * qy - hz * qz
    nx_ = qx + hx * qw + hy * qz - hz * qy
    ny_ = qy + hy * qw + hz * qx - hx * qz
    nz_ = qz + hz * qw + hx * qy - hy * qx
    ln = 1.0 / math.sqrt(nw_ * nw_ + nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
    qw, qx, qy, qz = nw_ * ln, nx_ * ln, ny_ * ln, nz_ * ln
    for k in range(nk):
        q[k] += dt * qd[k]
    return qw, qx, qy, qz


@numba.njit(cache=CACHE, inline="always")
def _modal_forces_exact(q, qd, s, pairs, bc, hq, force, tmp_p, prop, qfree, vfree):
    """Stage 1 with the exact propagator ``prop`` (K, 6): the stiffening (as :func:`_modal_forces`) held constant
    over the step; leaves the free end-of-step state ``qfree``/``vfree`` for :func:`_advance_exact`."""
    nk = q.shape[0]
    npair = pairs.shape[0]
    for k in range(nk):
        acc = 0.0
        for p in range(npair):
            acc += bc[k, p] * s[p]
        force[k] = -acc
    for p in range(npair):
        acc = 0.0
        for k in range(nk):
            acc += bc[k, p] * q[k]
        for p2 in range(npair):
            acc += hq[p, p2] * s[p2]
        tmp_p[p] = acc
    for p in range(npair):
        a = pairs[p, 0]
        b = pairs[p, 1]
        force[a] -= tmp_p[p] * q[b]
        force[b] -= tmp_p[p] * q[a]
    for k in range(nk):
        q0 = q[k]
        v0 = qd[k]
        fk = force[k]
        qfree[k] = prop[k, 0] * q0 + prop[k, 1] * v0 + prop[k, 4] * fk
        vfree[k] = prop[k, 2] * q0 + prop[k, 3] * v0 + prop[k, 5] * fk
        qd[k] = vfree[k]


@numba.njit(cache=CACHE, inline="always")
def _advance_exact(xf, vf, wf, q, qd, dt, qw, qx, qy, qz, qfree, vfree, rq):
    """Stage 4 with the exact propagator: the frame as :func:`_advance`; the modes at their free end state plus the
    contact's response ``rq (v - vfree)``. Returns the new quaternion."""
    nk = q.shape[0]
    for d in range(3):
        xf[d] += dt * vf[d]
    hx, hy, hz = 0.5 * dt * wf[0], 0.5 * dt * wf[1], 0.5 * dt * wf[2]
    nw_ = qw - hx * qx - hy * qy - hz * qz
    nx_ = qx + hx * qw + hy * qz - hz * qy
    ny_ = qy + hy * qw + hz * qx - hx * qz
    nz_ = qz + hz * qw + hx * qy - hy * qx
    ln = 1.0 / math.sqrt(nw_ * nw_ + nx_ * nx_ + ny_ * ny_ + nz_ * nz_)
    qw, qx, qy, qz = nw_ * ln, nx_ * ln, ny_ * ln, nz_ * ln
    for k in range(nk):
        q[k] = qfree[k] + rq[k] * (qd[k] - vfree[k])
    return qw, qx, qy, qz


@numba.njit(cache=CACHE, fastmath=FAST)
def modal_probe(prm, rest, pt, pr, us, omega, damp, pairs, bc, hq, cells, yaw_out, cu_out, cv_out):
    """Simulate one probe of the modal disc; fills the traces and returns (status, records written).

    ``pt``/``pr``: (N, 3, K) each tile's modal translation and rotation per mode (body frame); ``us``: (N, 3, P)
    the static foreshortening per product ``s_p = q_a q_b`` of ``pairs`` (P, 2); ``bc`` (K, P), ``hq`` (P, P) the
    cubic and quartic stiffening; ``omega``/``damp`` (K,) modal frequency and damping.
    """
    n = rest.shape[0]
    nk = omega.shape[0]
    npair = pairs.shape[0]
    dt = prm[params.P_DT]
    m = prm[params.P_MASS]
    mtot = m * n
    inv_mt = 1.0 / mtot
    ib0, ib1, ib2 = prm[M_IB0], prm[M_IB1], prm[M_IB2]
    n_iter = int(prm[M_NITER])
    n_steps = int(prm[params.P_NSTEPS])
    rec_every = int(prm[params.P_RECEVERY])
    kc = 0.25 * prm[params.P_KC]
    cc = 0.25 * prm[params.P_CC]
    hh = 0.5 * prm[M_H]
    grav = prm[params.P_G]
    fs = prm[M_FS] > 0.5
    mus, muk, vt = prm[params.P_MUS], prm[params.P_MUK], prm[params.P_VT]
    # state
    xf = np.empty(3)
    vf = np.zeros(3)
    wf = np.zeros(3)
    q = np.zeros(nk)
    qd = np.zeros(nk)
    s = np.zeros(npair)
    force = np.empty(nk)
    sk = np.empty(nk)
    for k in range(nk):
        sk[k] = 1.0 / (1.0 + dt * damp[k] + dt * dt * omega[k] * omega[k])
    tmp_p = np.empty(npair)
    rm = np.empty((3, 3))
    iw = np.empty((3, 3))  # world inverse inertia
    trot = np.empty((n, 3, 3))  # tile rotation in the body frame
    x = np.empty((n, 3))  # tile centres, world
    cdat = np.empty((4 * n, 7))  # corner offset from its tile centre c (3, world), f_spring, plate velocity (3)
    cimp = np.empty((4 * n, 3))
    tfirst = np.empty(n, dtype=np.int64)  # tiles in contact: their corners' range, the tile, its mobility
    tlast = np.empty(n, dtype=np.int64)
    ttile = np.empty(n, dtype=np.int64)
    wmob = np.empty((n, 6, 6))
    lv = np.empty(6)
    sc3a = np.empty((3, 3))
    sc3b = np.empty((3, 3))
    sc6 = np.empty((6, 6))
    dwr = np.empty(6)
    amob = np.zeros((n, 6, 6))
    _self_mobility(pt, pr, sk, amob)
    yaw0 = prm[params.P_YAW0]
    xf[0] = prm[params.P_U0]
    xf[1] = prm[params.P_V0]
    xf[2] = -prm[params.P_DEPTH0]
    qw, qx, qy, qz = math.cos(0.5 * yaw0), 0.0, 0.0, math.sin(0.5 * yaw0)
    yaw = yaw0
    n_rec = 0
    status = Status.OK
    for step in range(n_steps + 1):
        th, th_dot, xp, xp_dot = plate_at(prm, step * dt)
        s_th = math.sin(th)
        c_th = math.cos(th)
        pnx, pny, pnz = 0.0, -s_th, c_th
        _quat_matrix(qw, qx, qy, qz, rm)
        tile_w_min = _tile_geometry(q, s, pairs, rest, pt, pr, us, fs, xf, rm, trot, x, s_th, c_th)
        if step % rec_every == 0:
            vmax2 = _max_speed(x, xf, vf, wf, rm, pt, qd)
            extra = Status.OK
            if tile_w_min < prm[M_FOLDW]:
                extra = Status.FOLDED
            status, yaw, n_rec = record(x, rest, cells, xp, s_th, c_th, yaw, vmax2, extra, prm, yaw_out, cu_out,
                                        cv_out, n_rec)
            if status != Status.OK:
                break
        if step == n_steps:
            break
        _modal_forces(q, qd, s, pairs, bc, hq, omega, sk, force, tmp_p, dt)
        _frame_forces(vf, wf, rm, iw, dt, grav, ib0, ib1, ib2)
        n_tact = _active_tiles(hh, trot, rm, x, xf, s_th, c_th, th_dot, xp_dot, kc, cdat, cimp, tfirst, tlast, ttile,
                               inv_mt, iw, amob, wmob, sc3a, sc3b, sc6)
        _contact_sweeps(step, n_iter, n_tact, ttile, tfirst, tlast, wmob, x, xf, vf, wf, rm, iw, pt, pr, qd, sk, cdat,
                        cimp, lv, dwr, pnx, pny, pnz, cc, dt, mus, muk, vt, inv_mt)
        qw, qx, qy, qz = _advance(xf, vf, wf, q, qd, dt, qw, qx, qy, qz)
    return status, n_rec


@numba.njit(cache=CACHE, fastmath=FAST)
def modal_probe_exact(prm, rest, pt, pr, us, omega, damp, prop, pairs, bc, hq, cells, yaw_out, cu_out, cv_out):
    """:func:`modal_probe` with the exact modal propagator ``prop`` (K, 6) (:data:`INTEGRATORS`)."""
    n = rest.shape[0]
    nk = omega.shape[0]
    npair = pairs.shape[0]
    dt = prm[params.P_DT]
    m = prm[params.P_MASS]
    mtot = m * n
    inv_mt = 1.0 / mtot
    ib0, ib1, ib2 = prm[M_IB0], prm[M_IB1], prm[M_IB2]
    n_iter = int(prm[M_NITER])
    n_steps = int(prm[params.P_NSTEPS])
    rec_every = int(prm[params.P_RECEVERY])
    kc = 0.25 * prm[params.P_KC]
    cc = 0.25 * prm[params.P_CC]
    hh = 0.5 * prm[M_H]
    grav = prm[params.P_G]
    fs = prm[M_FS] > 0.5
    mus, muk, vt = prm[params.P_MUS], prm[params.P_MUK], prm[params.P_VT]
    # state
    xf = np.empty(3)
    vf = np.zeros(3)
    wf = np.zeros(3)
    q = np.zeros(nk)
    qd = np.zeros(nk)
    s = np.zeros(npair)
    force = np.empty(nk)
    sk = np.empty(nk)
    kick = (int(prm[M_EXACT]) & 4) != 0
    qfree = np.zeros(nk)
    vfree = np.zeros(nk)
    rq = np.zeros(nk)
    for k in range(nk):
        # the modal velocity per unit impulse (a force held over the step), the displacement per velocity change
        sk[k] = prop[k, 5] / dt
        rq[k] = dt if kick else prop[k, 4] / prop[k, 5]
    tmp_p = np.empty(npair)
    rm = np.empty((3, 3))
    iw = np.empty((3, 3))  # world inverse inertia
    trot = np.empty((n, 3, 3))  # tile rotation in the body frame
    x = np.empty((n, 3))  # tile centres, world
    cdat = np.empty((4 * n, 7))  # corner offset from its tile centre c (3, world), f_spring, plate velocity (3)
    cimp = np.empty((4 * n, 3))
    tfirst = np.empty(n, dtype=np.int64)  # tiles in contact: their corners' range, the tile, its mobility
    tlast = np.empty(n, dtype=np.int64)
    ttile = np.empty(n, dtype=np.int64)
    wmob = np.empty((n, 6, 6))
    lv = np.empty(6)
    sc3a = np.empty((3, 3))
    sc3b = np.empty((3, 3))
    sc6 = np.empty((6, 6))
    dwr = np.empty(6)
    amob = np.zeros((n, 6, 6))
    _self_mobility(pt, pr, sk, amob)
    yaw0 = prm[params.P_YAW0]
    xf[0] = prm[params.P_U0]
    xf[1] = prm[params.P_V0]
    xf[2] = -prm[params.P_DEPTH0]
    qw, qx, qy, qz = math.cos(0.5 * yaw0), 0.0, 0.0, math.sin(0.5 * yaw0)
    yaw = yaw0
    n_rec = 0
    status = Status.OK
    for step in range(n_steps + 1):
        th, th_dot, xp, xp_dot = plate_at(prm, step * dt)
        s_th = math.sin(th)
        c_th = math.cos(th)
        pnx, pny, pnz = 0.0, -s_th, c_th
        _quat_matrix(qw, qx, qy, qz, rm)
        tile_w_min = _tile_geometry(q, s, pairs, rest, pt, pr, us, fs, xf, rm, trot, x, s_th, c_th)
        if step % rec_every == 0:
            vmax2 = _max_speed(x, xf, vf, wf, rm, pt, qd)
            extra = Status.OK
            if tile_w_min < prm[M_FOLDW]:
                extra = Status.FOLDED
            status, yaw, n_rec = record(x, rest, cells, xp, s_th, c_th, yaw, vmax2, extra, prm, yaw_out, cu_out,
                                        cv_out, n_rec)
            if status != Status.OK:
                break
        if step == n_steps:
            break
        _modal_forces_exact(q, qd, s, pairs, bc, hq, force, tmp_p, prop, qfree, vfree)
        _frame_forces(vf, wf, rm, iw, dt, grav, ib0, ib1, ib2)
        n_tact = _active_tiles(hh, trot, rm, x, xf, s_th, c_th, th_dot, xp_dot, kc, cdat, cimp, tfirst, tlast, ttile,
                               inv_mt, iw, amob, wmob, sc3a, sc3b, sc6)
        _contact_sweeps(step, n_iter, n_tact, ttile, tfirst, tlast, wmob, x, xf, vf, wf, rm, iw, pt, pr, qd, sk, cdat,
                        cimp, lv, dwr, pnx, pny, pnz, cc, dt, mus, muk, vt, inv_mt)
        qw, qx, qy, qz = _advance_exact(xf, vf, wf, q, qd, dt, qw, qx, qy, qz, qfree, vfree, rq)
    return status, n_rec


@numba.njit(cache=CACHE, parallel=True)
def modal_batch_parallel(prm, rest, pt, pr, us, omega, damp, prop, pairs, bc, hq, cells, yaw_out, cu_out,
                         cv_out, status_out, nrec_out):
    """A batch over threads (one probe per iteration)."""
    for b in numba.prange(prm.shape[0]):
        if prm[b, M_EXACT] > 0.5:
            st, r = modal_probe_exact(prm[b], rest[b], pt[b], pr[b], us[b], omega[b], damp[b], prop[b], pairs, bc[b],
                                      hq[b], cells, yaw_out[b], cu_out[b], cv_out[b])
        else:
            st, r = modal_probe(prm[b], rest[b], pt[b], pr[b], us[b], omega[b], damp[b], pairs, bc[b], hq[b], cells,
                                yaw_out[b], cu_out[b], cv_out[b])
        status_out[b] = st
        nrec_out[b] = r


@numba.njit(cache=CACHE)
def modal_batch_serial(prm, rest, pt, pr, us, omega, damp, prop, pairs, bc, hq, cells, yaw_out, cu_out,
                       cv_out, status_out, nrec_out):
    """The same batch on the calling thread."""
    for b in range(prm.shape[0]):
        if prm[b, M_EXACT] > 0.5:
            st, r = modal_probe_exact(prm[b], rest[b], pt[b], pr[b], us[b], omega[b], damp[b], prop[b], pairs, bc[b],
                                      hq[b], cells, yaw_out[b], cu_out[b], cv_out[b])
        else:
            st, r = modal_probe(prm[b], rest[b], pt[b], pr[b], us[b], omega[b], damp[b], pairs, bc[b], hq[b], cells,
                                yaw_out[b], cu_out[b], cv_out[b])
        status_out[b] = st
        nrec_out[b] = r


def _arrays(spec: ProbeSpec, config: ModalDiscConfig, kmax: int):
    p = build_modal_params(spec.obj, config)
    n, k = p.geom.n_nodes, p.phi.shape[1]
    phi = np.zeros((6 * n, kmax))
    phi[:, :k] = p.phi
    ph = phi.reshape(n, 6, kmax)
    omega = np.zeros(kmax)
    damp = np.zeros(kmax)
    omega[:k] = p.omega
    damp[:k] = p.damp
    bc = np.zeros((kmax, len(p.pairs)))
    bc[:k] = p.b_cubic
    us = p.u_static.reshape(n, 6, -1)[:, :3, :]
    return (np.ascontiguousarray(ph[:, :3, :]), np.ascontiguousarray(ph[:, 3:, :]), np.ascontiguousarray(us),
            omega, damp, bc, p.h_quartic)


@lru_cache(maxsize=256)
def _propagator(obj, config: ModalDiscConfig, dt: float, kmax: int) -> np.ndarray:
    """(kmax, 6) the exact propagator of one object's modes (zero-padded modes: a free unit mass), cached: scipy's
    batched expm costs ~0.1 s a call, as much as a 1.7 s probe's whole kernel."""
    p = build_modal_params(obj, config)
    omega = np.zeros(kmax)
    damp = np.zeros(kmax)
    omega[:len(p.omega)] = p.omega
    damp[:len(p.damp)] = p.damp
    out = modal_propagator(omega, damp, dt)
    out.flags.writeable = False
    return out


def run_modal_arrays(probes: Sequence[ProbeSpec], dt: float = 1e-4, slip_limit: float = SLIP_LIMIT_M,
                     config: ModalDiscConfig = DEFAULT_MODAL, iterations: int = 1, parallel: bool | None = None,
                     law: ContactLaw = PAPER_CONTACT, record_interval_s: float = DEFAULT_RECORD_INTERVAL_S,
                     fold_tile_w: float = -0.2, integrator: str = "backward_euler") -> dict[str, np.ndarray]:
    """Run a batch with the modal disc; the keys of ``TileLinkPhysics.run_param_arrays`` plus "wall_s".
    ``integrator``: one of :data:`INTEGRATORS`, how each mode's spring-damper advances a step."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator = {integrator!r} must be one of {INTEGRATORS}")
    probes = list(probes)
    built = [build_modal_params(s.obj, config) for s in probes]
    kmax = max(p.phi.shape[1] for p in built)
    prm = np.stack([common_vector(s, dt, slip_limit, p.tile_mass, N_MODAL_PARAMS, contact_weight=0.25, law=law,
                                  record_interval_s=record_interval_s) for s, p in zip(probes, built, strict=True)])
    for b, p in enumerate(built):
        prm[b, M_H] = p.tile_size
        prm[b, M_IB0], prm[b, M_IB1], prm[b, M_IB2] = p.inertia_body
        prm[b, M_NITER] = iterations
        prm[b, M_FOLDW] = fold_tile_w
        prm[b, M_FS] = 1.0 if config.foreshortening else 0.0
        prm[b, M_EXACT] = float(INTEGRATORS[integrator])
    arrs = [_arrays(s, config, kmax) for s in probes]
    pt, pr, us, omega, damp, bc, hq = (np.stack([a[i] for a in arrs]) for i in range(7))
    prop = np.zeros((len(probes), kmax, 6))
    if integrator != "backward_euler":
        prop = np.stack([_propagator(s.obj, config, dt, kmax) for s in probes])
    rest = np.stack([p.geom.rest for p in built])
    pairs = built[0].pairs
    cells = built[0].geom.cells
    out = allocate_outputs(prm)
    if parallel is None:
        parallel = len(prm) > 1
    kernel = modal_batch_parallel if parallel else modal_batch_serial
    t0 = time.perf_counter()
    if integrator == "backward_euler":
        load_first(modal_probe, prm[0], rest[0], pt[0], pr[0], us[0], omega[0], damp[0], pairs, bc[0], hq[0], cells,
                   out["yaw"][0], out["cu"][0], out["cv"][0])
    else:
        load_first(modal_probe_exact, prm[0], rest[0], pt[0], pr[0], us[0], omega[0], damp[0], prop[0], pairs, bc[0],
                   hq[0], cells, out["yaw"][0], out["cu"][0], out["cv"][0])
    kernel(prm, rest, pt, pr, us, omega, damp, prop, pairs, bc, hq, cells, out["yaw"], out["cu"], out["cv"],
           out["status"], out["nrec"])
    out["wall_s"] = np.array(time.perf_counter() - t0)
    return out


class RigidModalPhysics:
    """The modal disc behind the backend's ``run`` interface (experimental: not one of the tile-link ``MODELS``).

    Args: ``dt`` s; ``config`` the reduction (:class:`rigid_modal.ModalDiscConfig`); ``iterations`` contact
    Gauss-Seidel sweeps a step; ``slip_limit`` m; ``integrator`` one of :data:`INTEGRATORS` (the modes' step).
    """

    def __init__(self, dt: float = 1e-4, config: ModalDiscConfig = DEFAULT_MODAL, iterations: int = 1,
                 slip_limit: float = SLIP_LIMIT_M, integrator: str = "backward_euler") -> None:
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator = {integrator!r} must be one of {INTEGRATORS}")
        if not (math.isfinite(dt) and 0.0 < dt <= 1e-3):
            raise ValueError(f"dt = {dt!r} s must be in (0, 1e-3]")
        if not (1 <= int(iterations) <= 20):
            raise ValueError(f"iterations = {iterations!r} must be in [1, 20]")
        self.dt = float(dt)
        self.config = config
        self.iterations = int(iterations)
        self.slip_limit = float(slip_limit)
        self.integrator = integrator
        self.name = "tilelink"
        self.model = "rigid_modal"

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        """Simulate the probes as one batch (``progress`` is accepted and ignored)."""
        from plate_env.physics.tilelink.backend import result_from_arrays

        probes = check_probes(probes)
        if not probes:
            return []
        raw = self.run_arrays(probes)
        wall = float(raw["wall_s"]) / len(probes)
        return [result_from_arrays(s, raw, b, self.dt, wall) for b, s in enumerate(probes)]

    def run_arrays(self, probes: Sequence[ProbeSpec]) -> dict[str, np.ndarray]:
        return run_modal_arrays(probes, self.dt, self.slip_limit, self.config, self.iterations,
                                integrator=self.integrator)

    def close(self) -> None:
        """Nothing to release."""
