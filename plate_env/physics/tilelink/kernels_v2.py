"""The point-mass kernel, v2: the v1 model (:mod:`plate_env.physics.tilelink.kernels`) on the disc's 8 x 8 grid.

Why another layout (measured, ``experiments/results/bench_kernel.md``): v1 loops over index lists (links,
triplets) that read and write nodes through indices; on this machine's compiler and CPU such loops stay scalar
(gathers are not chosen). Here the state is ``(3, G)`` over the slots of the 8 x 8 grid the 52 nodes sit on
(slot ``8 j + i`` at column i, row j, with ``PAD`` empty slots on both sides), so every joint, triplet and node
loop is a shifted, contiguous, elementwise operation over the 64 slots, which the compiler can vectorise; masks
zero the slots and pairs that do not exist. The implicit bending damper is applied in the symmetry basis of the
grid's two mirror flips: four blocks of 13 x 13 instead of a dense 52 x 52 matrix.

Arithmetic is plain IEEE-754 (no fastmath: no reassociation, no FMA contraction, no approximate functions) and
each sum runs in a fixed order, so the same inputs give bit-identical traces in any process, compiled or loaded
from numba's disk cache, and a batch repeats its single runs bit for bit (``tests/test_determinism.py``). The
numbers differ in the last bits from v1's (other order of sums); how far omega_B moves, in units of each probe's
standard error: ``experiments/results/bench_kernel.md``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from plate_env.core.probe import Status
from plate_env.physics.tilelink import params
from plate_env.physics.tilelink.contact import CONTACT_EXPONENT
from plate_env.physics.tilelink.kernels import plate_at, record

#: Grid side, slots.
SIDE = 8
#: Slots of the grid.
SLOTS = SIDE * SIDE
#: Empty slots before and after the grid (>= the largest offset, 2 rows), so shifted reads stay in the array.
PAD = 24
#: Joint directions as slot offsets: +u link, +v link, and the cells' two diagonals.
PAIR_OFFSETS = (1, SIDE, SIDE + 1, SIDE - 1)
#: Triplet directions (rows, columns) as slot offsets.
TRIPLET_OFFSETS = (1, SIDE)
#: Rows of the mask array: the four joint directions, the two triplet directions, the nodes.
M_NODE = 6
#: Orbits of four mirror images that the 52 nodes form (a constant, so the damper's loops have a known length).
QUAD = 13

_ENV = {"cache": True, "error_model": "numpy"}


@numba.njit(inline="always", **_ENV)
def grid_forces(x, v, f, masks, pair_rest, m, grav, kb, kin, cin, kap, fp):
    """Gravity, bending (explicit stiffness) and the in-plane spring-dampers into ``f`` (3, G), N.

    Each triplet's and joint's force is computed first (``kap`` (2, 3, G), ``fp`` (4, 3, G): scratch, zero in
    the padding), then each slot adds what acts on it in a fixed order; no loop writes what a later iteration
    reads, so all of them vectorise."""
    for t in range(2):
        o = TRIPLET_OFFSETS[t]
        for d in range(3):
            for s in range(PAD, PAD + SLOTS):
                kap[t, d, s] = masks[4 + t, s] * kb * (x[d, s - o] - 2.0 * x[d, s] + x[d, s + o])
    for p in range(4):
        o = PAIR_OFFSETS[p]
        rl = pair_rest[p]
        for s in range(PAD, PAD + SLOTS):
            mk = masks[p, s]
            dx = x[0, s + o] - x[0, s]
            dy = x[1, s + o] - x[1, s]
            dz = x[2, s + o] - x[2, s]
            ln = math.sqrt(dx * dx + dy * dy + dz * dz) + (1.0 - mk)  # no joint: 1, not 0/0
            inv = 1.0 / ln
            ex = dx * inv
            ey = dy * inv
            ez = dz * inv
            vrel = (v[0, s + o] - v[0, s]) * ex + (v[1, s + o] - v[1, s]) * ey + (v[2, s + o] - v[2, s]) * ez
            fs = mk * (kin * (ln - rl) + cin * vrel)
            fp[p, 0, s] = fs * ex
            fp[p, 1, s] = fs * ey
            fp[p, 2, s] = fs * ez
    for d in range(3):
        for s in range(PAD, PAD + SLOTS):
            f[d, s] = -m * grav * masks[M_NODE, s] if d == 2 else 0.0
        for t in range(2):
            o = TRIPLET_OFFSETS[t]
            for s in range(PAD, PAD + SLOTS):
                f[d, s] += (2.0 * kap[t, d, s] - kap[t, d, s - o]) - kap[t, d, s + o]
        for p in range(4):
            o = PAIR_OFFSETS[p]
            for s in range(PAD, PAD + SLOTS):
                f[d, s] += fp[p, d, s] - fp[p, d, s - o]


@numba.njit(inline="always", **_ENV)
def grid_damper(vs, v, blocks, quad, z, w):
    """``v = A vs`` with ``A`` the implicit damper as four parity blocks over the ``QUAD`` orbits of four mirror
    images: ``quad`` (QUAD, 4) their slots (a node, its mirror in u, in v, in both), ``blocks[p, q, o]`` block
    p's entry (o, q); ``z``, ``w`` (4, 3, QUAD): scratch."""
    for k in range(QUAD):
        sa, sb, sc, se = quad[k, 0], quad[k, 1], quad[k, 2], quad[k, 3]
        for d in range(3):
            z[0, d, k] = 0.5 * ((vs[d, sa] + vs[d, sb]) + (vs[d, sc] + vs[d, se]))
            z[1, d, k] = 0.5 * ((vs[d, sa] - vs[d, sb]) + (vs[d, sc] - vs[d, se]))
            z[2, d, k] = 0.5 * ((vs[d, sa] + vs[d, sb]) - (vs[d, sc] + vs[d, se]))
            z[3, d, k] = 0.5 * ((vs[d, sa] - vs[d, sb]) - (vs[d, sc] - vs[d, se]))
    for p in range(4):
        for d in range(3):
            for o in range(QUAD):
                w[p, d, o] = 0.0
            for q in range(QUAD):
                zq = z[p, d, q]
                for o in range(QUAD):
                    w[p, d, o] += blocks[p, q, o] * zq
    for k in range(QUAD):
        sa, sb, sc, se = quad[k, 0], quad[k, 1], quad[k, 2], quad[k, 3]
        for d in range(3):
            v[d, sa] = 0.5 * ((w[0, d, k] + w[1, d, k]) + (w[2, d, k] + w[3, d, k]))
            v[d, sb] = 0.5 * ((w[0, d, k] - w[1, d, k]) + (w[2, d, k] - w[3, d, k]))
            v[d, sc] = 0.5 * ((w[0, d, k] + w[1, d, k]) - (w[2, d, k] + w[3, d, k]))
            v[d, se] = 0.5 * ((w[0, d, k] - w[1, d, k]) - (w[2, d, k] - w[3, d, k]))


@numba.njit(inline="always", **_ENV)
def grid_contact(x, v, masks, fsp, prm, th_dot, xp_dot, s_th, c_th):
    """Plate contact at every node: implicit normal damper, Coulomb stick/slip (the law of :mod:`contact`).

    The spring ``k a^2.2`` first (one ``pow`` call per node in contact, a loop of its own; v1 calls ``exp`` and
    ``log``: 11 against 15 ns here), then every slot computes the rest
    and a select keeps its velocity where it is out of contact, as v1's branches do; ``fsp`` (G,): scratch."""
    m = prm[params.P_MASS]
    inv_m = 1.0 / m
    dt = prm[params.P_DT]
    cc = prm[params.P_CC]
    for s in range(PAD, PAD + SLOTS):
        depth = x[1, s] * s_th - x[2, s] * c_th
        fsp[s] = prm[params.P_KC] * math.pow(depth, CONTACT_EXPONENT) if depth > 0.0 else 0.0
    for s in range(PAD, PAD + SLOTS):
        pvx = xp_dot
        pvy = -th_dot * x[2, s]
        pvz = th_dot * x[1, s]
        rx = v[0, s] - pvx
        ry = v[1, s] - pvy
        rz = v[2, s] - pvz
        vn = -ry * s_th + rz * c_th
        fn = (fsp[s] - cc * vn) / (1.0 + dt * cc * inv_m)
        touch = (fsp[s] > 0.0) & (fn > 0.0) & (masks[M_NODE, s] > 0.0)
        vn_new = vn + dt * inv_m * fn
        tx = rx
        ty = ry + vn * s_th
        tz = rz - vn * c_th
        slip = math.sqrt(tx * tx + ty * ty + tz * tz)
        mu = prm[params.P_MUS] if slip < prm[params.P_VT] else prm[params.P_MUK]
        dv = mu * fn * dt * inv_m
        sc = 1.0 - dv / (slip + (slip <= 0.0))
        sc = 1.0 if slip <= 0.0 else (0.0 if dv >= slip else sc)
        v[0, s] = pvx + sc * tx if touch else v[0, s]
        v[1, s] = pvy + sc * ty - vn_new * s_th if touch else v[1, s]
        v[2, s] = pvz + sc * tz + vn_new * c_th if touch else v[2, s]


@numba.njit(**_ENV)
def pointmass_probe(prm, blocks, slot, quad, masks, pair_rest, rest, cells, yaw_out, cu_out, cv_out):
    """Simulate one point-mass probe; fills the traces and returns (status, records written).

    ``slot`` (N,): each node's slot in the padded grid; ``masks`` (7, G): joints per direction, triplets per
    direction, nodes; ``pair_rest`` (4,): rest length per joint direction, m; ``blocks``, ``quad``: see
    :func:`grid_damper` (:class:`plate_env.physics.tilelink.pointmass.GridLayout` builds them).
    """
    n = rest.shape[0]
    g = masks.shape[1]
    x = np.zeros((3, g))
    v = np.zeros((3, g))
    f = np.zeros((3, g))
    vs = np.zeros((3, g))
    fsp = np.zeros(g)
    kap = np.zeros((2, 3, g))
    fp = np.zeros((4, 3, g))
    z = np.empty((4, 3, QUAD))
    w = np.empty((4, 3, QUAD))
    pos = np.empty((n, 3))
    dt = prm[params.P_DT]
    step_m = dt / prm[params.P_MASS]
    n_steps = int(prm[params.P_NSTEPS])
    rec_every = int(prm[params.P_RECEVERY])
    cy = math.cos(prm[params.P_YAW0])
    sy = math.sin(prm[params.P_YAW0])
    for i in range(n):
        s = slot[i]
        x[0, s] = prm[params.P_U0] + cy * rest[i, 0] - sy * rest[i, 1]
        x[1, s] = prm[params.P_V0] + sy * rest[i, 0] + cy * rest[i, 1]
        x[2, s] = -prm[params.P_DEPTH0]
    yaw = prm[params.P_YAW0]
    n_rec = 0
    status = Status.OK
    for step in range(n_steps + 1):
        th, th_dot, xp, xp_dot = plate_at(prm, step * dt)
        s_th = math.sin(th)
        c_th = math.cos(th)
        if step % rec_every == 0:
            vmax2 = 0.0
            for i in range(n):
                s = slot[i]
                sp = v[0, s] ** 2 + v[1, s] ** 2 + v[2, s] ** 2
                if not (sp <= vmax2):
                    vmax2 = sp
                pos[i, 0] = x[0, s]
                pos[i, 1] = x[1, s]
                pos[i, 2] = x[2, s]
            status, yaw, n_rec = record(pos, rest, cells, xp, s_th, c_th, yaw, vmax2, Status.OK, prm, yaw_out,
                                        cu_out, cv_out, n_rec)
            if status != Status.OK:
                break
        if step == n_steps:
            break
        grid_forces(x, v, f, masks, pair_rest, prm[params.P_MASS], prm[params.P_G], prm[params.P_KB],
                    prm[params.P_KIN], prm[params.P_CIN], kap, fp)
        for d in range(3):
            for s in range(PAD, PAD + SLOTS):
                vs[d, s] = v[d, s] + step_m * f[d, s]
        grid_damper(vs, v, blocks, quad, z, w)
        grid_contact(x, v, masks, fsp, prm, th_dot, xp_dot, s_th, c_th)
        for d in range(3):
            for s in range(PAD, PAD + SLOTS):
                x[d, s] += dt * v[d, s]
    return status, n_rec


@numba.njit(parallel=True, **_ENV)
def pointmass_batch_parallel(prm, blocks, slot, quad, masks, pair_rest, rest, cells, yaw_out, cu_out, cv_out,
                             status_out, nrec_out):
    """Run a batch of probes over threads (one probe per iteration; each as :func:`pointmass_probe` alone)."""
    for b in numba.prange(prm.shape[0]):
        s, r = pointmass_probe(prm[b], blocks[b], slot, quad, masks, pair_rest[b], rest[b], cells, yaw_out[b],
                               cu_out[b], cv_out[b])
        status_out[b] = s
        nrec_out[b] = r


@numba.njit(**_ENV)
def pointmass_batch_serial(prm, blocks, slot, quad, masks, pair_rest, rest, cells, yaw_out, cu_out, cv_out,
                           status_out, nrec_out):
    """The same batch on the calling thread."""
    for b in range(prm.shape[0]):
        s, r = pointmass_probe(prm[b], blocks[b], slot, quad, masks, pair_rest[b], rest[b], cells, yaw_out[b],
                               cu_out[b], cv_out[b])
        status_out[b] = s
        nrec_out[b] = r
