"""A reduced-coordinate (floating frame of reference) form of the rigid-tile disc (issue 34; experimental).

The same disc as :mod:`plate_env.physics.tilelink.rigid` in its rigid limit (:data:`rigid.RIGID_LIMIT_CONFIG`: same
tiles, joints, bending stiffness ``k_b`` from the same modal analysis), written in other coordinates:

* the disc's rigid motion, exact: a frame at the mass centre (position, unit quaternion, velocity, angular
  velocity) with the flat disc's inertia;
* ``K`` flexible modes of the linearised free disc (mass-normalised eigenvectors of ``K phi = w^2 M phi``, which
  are mass-orthogonal to the rigid motions: mean axes) below a stated cut-off frequency, the free twist included;
  each mode a linear spring-damper (modal stiffness ``w^2``, modal damping ``phi^T C phi``);
* the joints' geometric stiffening, by implicit condensation: the exact joint rows (the kernel's own row formulas)
  are expanded to second order in the ``N`` lowest out-of-plane modes, ``C = J d + G s(q)`` with ``s`` the
  products ``q_a q_b``; the modes above the cut-off (the held rows' kilohertz modes) are solved statically for
  each ``s``, which leaves a cubic (``q^T B s``) and a quartic (``s^T H s / 2``) term in the elastic energy. The
  static modes' displacement ``U s`` (the foreshortening of large bends, mostly in-plane) moves the tile centres
  in the observation and the contact geometry (kinematic only: the impulses act through the linear modes).

Neglected (stated): the frame/mode inertial coupling (Coriolis and centrifugal terms between the disc's spin,
~10 rad/s, and the modes, >= 30 rad/s), the inertia of the static part ``U s``, the change of the disc's inertia
tensor with the bend, terms of the joint rows beyond second order. Contact: the shared law at the 4 corners of
every tile (:mod:`plate_env.physics.tilelink.contact`, a quarter of the tile's coefficients per corner), corner
positions from the frame, the tile's modal displacement and rotation.

Not registered as a backend model: its accuracy and speed against the converged rigid limit are in
``experiments/results/rigid_modal.md``, the design notes in ``experiments/results/rigid_modal_notes.md``.
SI units throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg

from plate_env.core.objects import ObjectSpec
from plate_env.physics.tilelink.geometry import DiscGeometry, disc_geometry
from plate_env.physics.tilelink.rigid import (
    DOF_PER_TILE,
    RIGID_LIMIT_CONFIG,
    RigidTileConfig,
    _row_values,
    bending_stiffness,
    joint_jacobian,
    linear_stiffness,
    mass_matrix,
    out_of_plane_dofs,
    tile_inertia,
)


@dataclass(frozen=True)
class ModalDiscConfig:
    """Reduction settings of the modal disc.

    Attributes:
        cutoff_hz: flexible modes below this frequency (Hz) are dynamic; the rest are condensed statically.
        max_modes: at most this many dynamic modes (the lowest; 0: no cap beyond the cut-off).
        n_nonlinear: the lowest this many flexible out-of-plane modes carry the second-order joint terms
            (0: the linear floating frame).
        foreshortening: the static displacement ``U s`` moves the tile centres (kinematic).
        fd_rad: finite-difference step of the second-order expansion, as the largest tile rotation (rad).
        joints: the rigid-tile joint values the modes are computed from (the rigid limit's).
    """

    cutoff_hz: float = 200.0
    max_modes: int = 0
    n_nonlinear: int = 10
    foreshortening: bool = True
    fd_rad: float = 1e-3
    joints: RigidTileConfig = RIGID_LIMIT_CONFIG

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cutoff_hz) and 1.0 <= self.cutoff_hz <= 2000.0):
            raise ValueError(f"cutoff_hz = {self.cutoff_hz!r} must be in [1, 2000] Hz")
        if not (0 <= int(self.max_modes) <= 306):
            raise ValueError(f"max_modes = {self.max_modes!r} must be in [0, 306]")
        if not (0 <= int(self.n_nonlinear) <= 80):
            raise ValueError(f"n_nonlinear = {self.n_nonlinear!r} must be in [0, 80]")
        if not (math.isfinite(self.fd_rad) and 1e-6 <= self.fd_rad <= 1e-1):
            raise ValueError(f"fd_rad = {self.fd_rad!r} rad must be in [1e-6, 0.1]")


#: The default reduction.
DEFAULT_MODAL = ModalDiscConfig()


@dataclass(frozen=True)
class ModalDiscParams:
    """Arrays of one object's modal disc (SI). ``phi``: (6N, K) mass-normalised mode shapes in the body frame
    (per tile x, y, z, rot_x, rot_y, rot_z); ``omega``/``damp``: (K,) modal frequency rad/s and damping 1/s
    (``phi^T C phi``); ``nl_index``: (N_nl,) which modes carry the second-order terms; ``pairs``: (P, 2) their
    products; ``b_cubic``: (K, P); ``h_quartic``: (P, P); ``u_static``: (6N, P) the static modes' displacement per
    product; ``inertia_body``: (3,) principal inertia of the flat disc about its centre, kg m^2."""

    geom: DiscGeometry
    tile_mass: float
    tile_size: float
    k_bending: float
    phi: np.ndarray
    omega: np.ndarray
    damp: np.ndarray
    nl_index: np.ndarray
    pairs: np.ndarray
    b_cubic: np.ndarray
    h_quartic: np.ndarray
    u_static: np.ndarray
    inertia_body: np.ndarray
    omegas_all: np.ndarray


def _rotvec_matrices(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of rotation vectors (n, 3) (Rodrigues)."""
    ang = np.linalg.norm(theta, axis=1)
    safe = np.where(ang > 0.0, ang, 1.0)
    sa = np.where(ang > 0.0, np.sin(ang) / safe, 1.0)
    ca = np.where(ang > 0.0, (1.0 - np.cos(ang)) / safe**2, 0.5)
    kx = np.zeros((len(theta), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -theta[:, 2], theta[:, 1], -theta[:, 0]
    kx[:, 1, 0], kx[:, 2, 0], kx[:, 2, 1] = theta[:, 2], -theta[:, 1], theta[:, 0]
    return np.eye(3) + sa[:, None, None] * kx + ca[:, None, None] * (kx @ kx)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def joint_rows(geom: DiscGeometry, disp: np.ndarray) -> np.ndarray:
    """The exact joint row values (J, 5) of the rigid-tile kernel (``rigid_kernels._joint_setup``) for a tile
    displacement field ``disp`` (6N: per tile x, y, z and a rotation vector) from the flat rest state, m and rad."""
    n = geom.n_nodes
    d = disp.reshape(n, DOF_PER_TILE)
    x = np.column_stack([geom.rest, np.zeros(n)]) + d[:, :3]
    rot = _rotvec_matrices(d[:, 3:])
    hh = 0.5 * geom.spacing
    a, b = geom.links[:, 0], geom.links[:, 1]
    o = geom.link_dir.astype(np.int64)
    e1a = rot[a, :, o]
    e1b = rot[b, :, o]
    na, nb = rot[a, :, 2], rot[b, :, 2]
    t1 = _unit(e1a + e1b)
    nn = na + nb
    nn = _unit(nn - np.sum(nn * t1, axis=1, keepdims=True) * t1)
    t2 = np.cross(nn, t1)
    dd = x[b] - hh * e1b - x[a] - hh * e1a
    c = np.cross(na, nb)
    return np.column_stack([np.sum(dd * t1, 1), np.sum(dd * t2, 1), np.sum(dd * nn, 1),
                            np.arctan2(np.sum(c * t2, 1), np.sum(na * nb, 1)),
                            np.sum(np.cross(e1a, e1b) * nn, 1)])


def _rigid_modes(geom: DiscGeometry) -> np.ndarray:
    """(6N, 6) the rigid translations and small rotations about the centre of the flat disc."""
    n = geom.n_nodes
    r = np.zeros((DOF_PER_TILE * n, 6))
    for i, (u, v) in enumerate(geom.rest):
        o = DOF_PER_TILE * i
        r[o:o + 3, 0:3] = np.eye(3)
        # small rotation w: displacement w x (u, v, 0), tile rotation w
        for k, w in enumerate(np.eye(3)):
            r[o:o + 3, 3 + k] = np.cross(w, (u, v, 0.0))
            r[o + 3:o + 6, 3 + k] = w
    return r


@lru_cache(maxsize=64)
def build_modal_params(obj: ObjectSpec, config: ModalDiscConfig = DEFAULT_MODAL) -> ModalDiscParams:
    """The modal disc of one object (see the module docstring), ``k_b`` hitting ``obj.omega_n``."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _build(obj, config)


def _build(obj: ObjectSpec, config: ModalDiscConfig) -> ModalDiscParams:
    geom = disc_geometry(obj.diameter)
    n = geom.n_nodes
    m = obj.mass / n
    joints = config.joints
    k_b = bending_stiffness(obj, joints)
    row_k, row_c = _row_values(geom, m, k_b, obj.omega_n, joints)
    kmat = linear_stiffness(geom, row_k)
    mmat = mass_matrix(geom, m)
    jac = joint_jacobian(geom)
    wrow = np.tile(row_k, len(geom.links))
    crow = np.tile(row_c, len(geom.links))
    cmat = jac.T @ (jac * crow[:, None])
    evals, evecs = scipy.linalg.eigh(kmat, mmat)
    omegas = np.sqrt(np.clip(evals, 0.0, None))
    n_zero = int(np.sum(omegas < 1e-2))
    # the zero space holds the 6 rigid motions and the free twist: keep its part mass-orthogonal to the rigid ones
    rig = _rigid_modes(geom)
    zero = evecs[:, :n_zero]
    proj = zero - rig @ np.linalg.solve(rig.T @ mmat @ rig, rig.T @ mmat @ zero)
    uu, sv, _ = np.linalg.svd(np.sqrt(np.diag(mmat))[:, None] * proj, full_matrices=False)
    twist = [uu[:, k] / np.sqrt(np.diag(mmat)) for k in range(len(sv)) if sv[k] > 1e-6 * sv[0]]
    if len(twist) != n_zero - 6:
        raise ValueError(f"expected {n_zero - 6} non-rigid zero modes, found {len(twist)}")
    flex = np.column_stack(twist + [evecs[:, k] for k in range(n_zero, len(omegas))])
    flex /= np.sqrt(np.einsum("ik,ij,jk->k", flex, mmat, flex))
    wflex = np.concatenate([np.zeros(len(twist)), omegas[n_zero:]])
    dyn = wflex < 2 * math.pi * config.cutoff_hz
    if config.max_modes:
        dyn &= np.arange(len(wflex)) < config.max_modes
    phi_d, phi_s = flex[:, dyn], flex[:, ~dyn]
    w_d, w_s = wflex[dyn], wflex[~dyn]
    damp = np.einsum("ik,ij,jk->k", phi_d, cmat, phi_d)
    oop = out_of_plane_dofs(geom)
    is_oop = np.array([(phi_d[oop, k] ** 2 * np.diag(mmat)[oop]).sum() > 0.5 for k in range(phi_d.shape[1])])
    nl_index = np.flatnonzero(is_oop)[:config.n_nonlinear]
    pairs = np.array([(a, b) for ia, a in enumerate(nl_index) for b in nl_index[ia:]], dtype=np.int64).reshape(-1, 2)
    kdim, npair = phi_d.shape[1], len(pairs)
    g = np.zeros((5 * len(geom.links), npair))
    if npair:
        rot_dofs = np.zeros(DOF_PER_TILE * n, dtype=bool)
        for dd_ in (3, 4, 5):
            rot_dofs[dd_::DOF_PER_TILE] = True

        def rows(vec):
            return joint_rows(geom, vec).ravel()

        c0 = rows(np.zeros(DOF_PER_TILE * n))
        eps = {a: config.fd_rad / np.abs(phi_d[rot_dofs, a]).max() for a in nl_index}
        for p, (a, b) in enumerate(pairs):
            ea, eb = eps[a] * phi_d[:, a], eps[b] * phi_d[:, b]
            if a == b:
                sec = (rows(ea) - 2 * c0 + rows(-ea)) / eps[a] ** 2
                g[:, p] = 0.5 * sec
            else:
                g[:, p] = (rows(ea + eb) - rows(ea - eb) - rows(-ea + eb) + rows(-ea - eb)) / (4 * eps[a] * eps[b])
    wg = wrow[:, None] * g
    b_cubic = phi_d.T @ jac.T @ wg
    z = phi_s.T @ jac.T @ wg
    h_quartic = g.T @ wg - z.T @ (z / (w_s[:, None] ** 2))
    h_quartic = 0.5 * (h_quartic + h_quartic.T)
    u_static = -phi_s @ (z / (w_s[:, None] ** 2))
    ixx, izz = tile_inertia(m, geom.spacing)
    ru, rv = geom.rest[:, 0], geom.rest[:, 1]
    inertia_body = np.array([m * (rv ** 2).sum() + n * ixx, m * (ru ** 2).sum() + n * ixx,
                             m * (ru ** 2 + rv ** 2).sum() + n * izz])
    if kdim == 0:
        raise ValueError(f"cutoff_hz = {config.cutoff_hz} keeps no flexible mode")
    return ModalDiscParams(geom=geom, tile_mass=m, tile_size=geom.spacing, k_bending=k_b, phi=phi_d, omega=w_d,
                           damp=damp, nl_index=nl_index, pairs=pairs, b_cubic=b_cubic, h_quartic=h_quartic,
                           u_static=u_static, inertia_body=inertia_body, omegas_all=omegas)


#: Columns of :func:`modal_propagator`'s (K, 6) array.
PROP_QQ, PROP_QV, PROP_VQ, PROP_VV, PROP_GQ, PROP_GV = range(6)


def modal_propagator(omega: np.ndarray, damp: np.ndarray, dt: float, method: str = "exact") -> np.ndarray:
    """One step of ``dt`` s of each modal oscillator ``q'' + c q' + w^2 q = f`` (``omega`` = w rad/s, ``damp`` = c
    1/s, arrays (K,)) as a (K, 6) array: ``q1 = P_QQ q0 + P_QV v0 + P_GQ f``, ``v1 = P_VQ q0 + P_VV v0 + P_GV f``
    with ``f`` held constant over the step (columns ``PROP_*``).

    ``method="exact"``: the exact state-transition matrix and constant-force response (the exponential of the
    augmented 3x3 system), so the linear frequency and damping of every mode are exact at any step.
    ``method="backward_euler"``: the kernel's semi-implicit scheme written the same way (``v1 = (v0 + dt (f - w^2
    q0)) / (1 + dt c + dt^2 w^2)``, ``q1 = q0 + dt v1``), for comparison.
    """
    omega = np.asarray(omega, dtype=float)
    damp = np.asarray(damp, dtype=float)
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt = {dt!r} s must be positive and finite")
    if omega.shape != damp.shape or omega.ndim != 1:
        raise ValueError(f"omega {omega.shape} and damp {damp.shape} must be equal 1-d shapes")
    out = np.empty((len(omega), 6))
    if method == "backward_euler":
        sk = 1.0 / (1.0 + dt * damp + dt * dt * omega**2)
        out[:, PROP_VQ] = -dt * omega**2 * sk
        out[:, PROP_VV] = sk
        out[:, PROP_GV] = dt * sk
        out[:, PROP_QQ] = 1.0 + dt * out[:, PROP_VQ]
        out[:, PROP_QV] = dt * sk
        out[:, PROP_GQ] = dt * dt * sk
        return out
    if method != "exact":
        raise ValueError(f"method = {method!r} must be 'exact' or 'backward_euler'")
    aug = np.zeros((len(omega), 3, 3))
    aug[:, 0, 1] = dt
    aug[:, 1, 0] = -dt * omega**2
    aug[:, 1, 1] = -dt * damp
    aug[:, 1, 2] = dt
    e = scipy.linalg.expm(aug)
    out[:, PROP_QQ], out[:, PROP_QV], out[:, PROP_GQ] = e[:, 0, 0], e[:, 0, 1], e[:, 0, 2]
    out[:, PROP_VQ], out[:, PROP_VV], out[:, PROP_GV] = e[:, 1, 0], e[:, 1, 1], e[:, 1, 2]
    return out
