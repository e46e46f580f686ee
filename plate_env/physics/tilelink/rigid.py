"""The paper's tile-link model with rigid tiles (the faithful version of Section 3.2).

Each of the 52 virtual tiles is a rigid square plate of side ``h = diameter / 8`` and mass ``m = mass / 52``
(thin-plate inertia ``I_xx = I_yy = m h^2 / 12``, ``I_zz = m h^2 / 6`` about its centre, gyroscopic term
included). The 88 joint units sit at the midpoints of the shared edges. In the joint frame (``t1`` along the link
between the two tile centres, ``t2`` along the shared edge, ``n`` the mean tile normal) a joint unit has

* compression/tension along ``t1``: spring-damper ``k_inplane`` (N/m), damping ratio ``zeta_inplane``;
* bending about the edge ``t2``: rotational spring-damper ``k_b`` (N m/rad), stiffness-proportional damper with
  damping ratio ``zeta_bending`` in the first free bending mode;
* torsion about ``t1``: free (the paper's free torsion joint);
* the remaining relative motions (translation of the joint point along ``t2`` and ``n``, rotation about ``n``)
  held "rigid": very stiff spring-dampers (``omega_rigid`` rad/s, critically damped in each row's rest effective
  mass) that the kernel integrates implicitly, so they do not bound the time step.

``k_b`` is set by modal analysis (:func:`plate_env.physics.tilelink.modal.modal_analysis`) of the model the
kernel integrates, linearised about the flat free state, so that the first free bending eigenfrequency equals the
object's ``omega_n``. Contact with the plate is the shared Eqs. (3)-(4) law
(:mod:`plate_env.physics.tilelink.contact`) applied at each tile's 4 corners with a quarter of the tile's
``k_contact`` and ``c_contact`` each (a flat tile then gets exactly the paper's per-link law; a tilted tile
touches at its lowest corners, the "surface of the virtual link"). SI units throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from plate_env.core.objects import ObjectSpec
from plate_env.physics.tilelink.geometry import DiscGeometry, disc_geometry
from plate_env.physics.tilelink.modal import ModalResult, modal_analysis

#: Degrees of freedom per tile in the linearised model: x, y, z, rot_x, rot_y, rot_z (small rotations, world).
DOF_PER_TILE = 6


@dataclass(frozen=True)
class RigidTileConfig:
    """Joint and solver values the paper does not give (chosen, documented).

    Attributes:
        k_inplane: compression/tension stiffness of a joint, N/m (the point-mass model's value).
        zeta_inplane: damping ratio of the compression row in its rest effective mass.
        zeta_bending: damping ratio of the first free bending mode (stiffness-proportional damper).
        omega_rigid: natural frequency of the "rigid" rows (stiff spring-dampers), rad/s.
        zeta_rigid: damping ratio of the rigid rows.
        iterations: Gauss-Seidel sweeps over the joints per step (warm started).
        block_refresh: the joints' 3x3/2x2 block inverses are rebuilt every this many steps (0: only at the
            start). They set GS's convergence rate, not its fixed point (rebuilding every step against every
            10th: ``experiments/results/dt_error_sources.md``).
        contact_points: plate contact sampling per tile; only 4 (the corners) is implemented.
        fold_angle: a joint bending angle beyond this (rad) ends the probe as FOLDED (tiles would pass
            through each other at pi; the joint spring's angle is exact up to +-pi).
        fold_tile_w: a tile whose normal's plate-normal component falls below this (the tile turned upside
            down while the disc is not overturned) ends the probe as FOLDED.
        energy_rel_tol: the disc's mechanical energy may exceed its start value plus the work the plate did on
            it by at most this fraction of the plate's absolute work ...
        energy_abs_tol: ... plus this many joules; more ends the probe as RUNAWAY.
    """

    k_inplane: float = 300.0
    zeta_inplane: float = 0.2
    zeta_bending: float = 0.1
    omega_rigid: float = 5000.0
    zeta_rigid: float = 1.0
    iterations: int = 2
    contact_points: int = 4
    fold_angle: float = math.radians(150.0)
    fold_tile_w: float = -0.2
    energy_rel_tol: float = 0.1
    energy_abs_tol: float = 2e-4
    block_refresh: int = 10

    def __post_init__(self) -> None:
        if self.contact_points != 4:
            raise ValueError("only 4 contact points per tile (its corners) are implemented")
        if int(self.block_refresh) < 0:
            raise ValueError(f"block_refresh = {self.block_refresh!r} must be >= 0")
        if not (1 <= int(self.iterations) <= 100):
            raise ValueError(f"iterations = {self.iterations!r} must be in [1, 100]")
        for label, value in (("k_inplane", self.k_inplane), ("omega_rigid", self.omega_rigid)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{label} = {value!r} must be positive")


#: The joint rows in their rigid limit (``model="rigid_limit"``, at dt = 2.5e-5 s): omega_B stops moving with the
#: rows' stiffness from ~20000 rad/s, and stiffer rows need a smaller step (omega_B against the rows' stiffness
#: and against dt: ``experiments/results/bench_models.md``).
RIGID_LIMIT_CONFIG = RigidTileConfig(omega_rigid=40000.0, iterations=4)

#: ``model="rigid_fast"`` (issue 26): the rigid limit's rows integrated by small steps with one Gauss-Seidel sweep
#: each (the velocity-level form of XPBD's compliant constraints, Macklin et al. 2019: "one iteration per substep")
#: at :data:`params.DEFAULT_DT` ``["rigid_fast"]`` = 2.5e-5 s: the rigid limit at ~1/3 of its cost. Chosen by
#: measurement against the converged rigid limit (dt 6.25e-6 s); accuracy, speed and the routes that did not reach
#: 10x real time: ``experiments/results/rigid_fast.md``.
RIGID_FAST_CONFIG = RigidTileConfig(omega_rigid=40000.0, iterations=1)

#: Each rigid-tile model's joint and solver values.
MODEL_CONFIGS = {"rigid": RigidTileConfig(), "rigid_limit": RIGID_LIMIT_CONFIG, "rigid_fast": RIGID_FAST_CONFIG}


@dataclass(frozen=True)
class RigidTileParams:
    """Numbers the rigid-tile kernel needs for one object (SI units).

    Row order of the joint arrays: 0 compression (t1), 1 edge translation (t2), 2 normal translation (n),
    3 bending (rotation about t2), 4 rotation about n. ``row_k``/``row_c`` are each row's stiffness and damping
    (N/m and N s/m for rows 0-2, N m/rad and N m s/rad for rows 3-4).
    """

    geom: DiscGeometry
    tile_mass: float
    tile_size: float
    inertia_xx: float
    inertia_zz: float
    k_bending: float
    row_k: np.ndarray
    row_c: np.ndarray
    modal: ModalResult


def joint_order(geom: DiscGeometry) -> np.ndarray:
    """Order in which the solver visits the joints: four colour classes (u-links from even/odd columns, v-links
    from even/odd rows), so consecutive joints never share a tile and their Gauss-Seidel updates do not wait on
    each other. Any order is a valid Gauss-Seidel sweep; this one was chosen for speed over the row order."""
    grid = np.rint(geom.rest / geom.spacing - 0.5).astype(np.int64)
    a = geom.links[:, 0]
    colour = np.where(geom.link_dir == 0, grid[a, 0] % 2, 2 + grid[a, 1] % 2)
    return np.argsort(colour, kind="stable")


def tile_inertia(tile_mass: float, tile_size: float) -> tuple[float, float]:
    """Thin square plate inertia about its centre, kg m^2: (in-plane axes, normal axis)."""
    ixx = tile_mass * tile_size**2 / 12.0
    return ixx, 2.0 * ixx


def joint_frames(geom: DiscGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest joint frames (J, 3) each: link direction t1, edge direction t2 = n x t1, normal n = e_z."""
    nj = len(geom.links)
    t1 = np.zeros((nj, 3))
    t1[geom.link_dir == 0, 0] = 1.0
    t1[geom.link_dir == 1, 1] = 1.0
    nrm = np.zeros((nj, 3))
    nrm[:, 2] = 1.0
    t2 = np.cross(nrm, t1)
    return t1, t2, nrm


def joint_jacobian(geom: DiscGeometry) -> np.ndarray:
    """Rest Jacobian of the 5 joint rows (5 J x 6 N): row 5*j + r, order as in :class:`RigidTileParams`."""
    n, nj = geom.n_nodes, len(geom.links)
    h = geom.spacing
    t1, t2, nrm = joint_frames(geom)
    jac = np.zeros((5 * nj, DOF_PER_TILE * n))
    for j, (a, b) in enumerate(geom.links):
        ra = 0.5 * h * t1[j]
        rb = -0.5 * h * t1[j]
        ia, ib = DOF_PER_TILE * a, DOF_PER_TILE * b
        for r, axis in enumerate((t1[j], t2[j], nrm[j])):
            row = 5 * j + r
            jac[row, ia:ia + 3] = -axis
            jac[row, ia + 3:ia + 6] = -np.cross(ra, axis)
            jac[row, ib:ib + 3] = axis
            jac[row, ib + 3:ib + 6] = np.cross(rb, axis)
        for r, axis in ((3, t2[j]), (4, nrm[j])):
            row = 5 * j + r
            jac[row, ia + 3:ia + 6] = -axis
            jac[row, ib + 3:ib + 6] = axis
    return jac


def mass_matrix(geom: DiscGeometry, tile_mass: float) -> np.ndarray:
    """Diagonal mass matrix (6N x 6N): m, m, m, I_xx, I_yy, I_zz per tile (kg, kg m^2)."""
    ixx, izz = tile_inertia(tile_mass, geom.spacing)
    return np.diag(np.tile([tile_mass, tile_mass, tile_mass, ixx, ixx, izz], geom.n_nodes))


def row_effective_masses(geom: DiscGeometry, tile_mass: float) -> np.ndarray:
    """Rest effective mass (kg or kg m^2) of each of the 5 row types: 1 / (J M^-1 J^T) of an interior joint."""
    jac = joint_jacobian(geom)
    minv = 1.0 / np.diag(mass_matrix(geom, tile_mass))
    return np.array([1.0 / float((jac[r] ** 2) @ minv) for r in range(5)])


def _row_values(geom: DiscGeometry, tile_mass: float, k_bending: float, omega_n: float,
                config: RigidTileConfig) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and damping of the 5 row types (see :class:`RigidTileParams`)."""
    meff = row_effective_masses(geom, tile_mass)
    k = np.empty(5)
    c = np.empty(5)
    k[0] = config.k_inplane
    c[0] = 2.0 * config.zeta_inplane * math.sqrt(config.k_inplane * meff[0])
    for r in (1, 2, 4):
        k[r] = meff[r] * config.omega_rigid**2
        c[r] = 2.0 * config.zeta_rigid * meff[r] * config.omega_rigid
    k[3] = k_bending
    c[3] = 2.0 * config.zeta_bending / omega_n * k_bending
    return k, c


def linear_stiffness(geom: DiscGeometry, row_k: np.ndarray) -> np.ndarray:
    """Stiffness matrix (6N x 6N) of the free disc linearised about the flat rest state: sum k_r J_r^T J_r."""
    jac = joint_jacobian(geom)
    weights = np.tile(row_k, len(geom.links))
    return jac.T @ (jac * weights[:, None])


def out_of_plane_dofs(geom: DiscGeometry) -> np.ndarray:
    """Boolean mask of the out-of-plane dofs (z, rot_x, rot_y) in the 6N vector."""
    mask = np.zeros(DOF_PER_TILE * geom.n_nodes, dtype=bool)
    for d in (2, 3, 4):
        mask[d::DOF_PER_TILE] = True
    return mask


def modal(obj: ObjectSpec, k_bending: float, config: RigidTileConfig = RigidTileConfig()) -> ModalResult:
    """Modal analysis of the linearised free rigid-tile disc with bending stiffness ``k_bending`` (N m/rad).

    This is the model the kernel integrates (the rigid rows as their stiff springs).
    """
    geom = disc_geometry(obj.diameter)
    m = obj.mass / geom.n_nodes
    row_k, _ = _row_values(geom, m, k_bending, obj.omega_n, config)
    return modal_analysis(linear_stiffness(geom, row_k), mass_matrix(geom, m), out_of_plane_dofs(geom))


@lru_cache(maxsize=256)
def bending_stiffness(obj: ObjectSpec, config: RigidTileConfig = RigidTileConfig(), rel_tol: float = 1e-4) -> float:
    """Joint bending stiffness k_b (N m/rad) whose first free bending eigenfrequency is ``obj.omega_n``.

    Out of plane only the bending springs and the (k_b-independent) rigid normal rows act, so omega_1^2 is
    nearly proportional to k_b: start from a unit-k_b analysis and refine with ``k_b *= (target/omega_1)^2``.
    """
    k_b = 1e-4
    for _ in range(8):
        w1 = modal(obj, k_b, config).omega_bending
        ratio = obj.omega_n / w1
        k_b *= ratio**2
        if abs(ratio - 1.0) < rel_tol:
            break
    return k_b


def build_params(obj: ObjectSpec, config: RigidTileConfig = RigidTileConfig()) -> RigidTileParams:
    """All rigid-tile parameters of one object, with ``k_b`` hitting ``obj.omega_n``."""
    geom = disc_geometry(obj.diameter)
    m = obj.mass / geom.n_nodes
    k_b = bending_stiffness(obj, config)
    row_k, row_c = _row_values(geom, m, k_b, obj.omega_n, config)
    ixx, izz = tile_inertia(m, geom.spacing)
    return RigidTileParams(geom=geom, tile_mass=m, tile_size=geom.spacing, inertia_xx=ixx, inertia_zz=izz,
                           k_bending=k_b, row_k=row_k, row_c=row_c, modal=modal(obj, k_b, config))
