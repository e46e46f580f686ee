"""The paper's tile-link model reduced to point masses (fast option).

Each of the 52 virtual tiles is a node of mass ``m = mass / 52`` at the tile centre. The 88 joint units act as

* compression/tension: a spring-damper along each joint (``k_inplane``, damping ratio ``zeta_inplane``);
* bending: a discrete-curvature energy ``k_b/2 |x_a - 2 x_b + x_c|^2`` on the collinear neighbour triplets along
  rows and columns (point masses have no rotation, so bending at a joint needs its two neighbours). It is
  rotation invariant and linear, and leaves the twist free, as the paper's free torsion joint does. Its damper is
  stiffness-proportional (damping ratio ``zeta_bending`` in the first bending mode) and integrated implicitly
  with a constant pre-inverted matrix, so stiff objects (up to 50pi and beyond) do not shrink the time step;
* in-plane shape: point masses joined only by the 88 joints shear instead of turning, so each 2x2 group of tiles
  also has diagonal spring-dampers (the rigid tiles of the faithful model hold this shape by themselves).

``k_b`` is set by modal analysis so the first free bending eigenfrequency equals the object's ``omega_n``.
The contact with the plate is the shared :mod:`plate_env.physics.tilelink.contact` law applied at each node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from plate_env.core.objects import ObjectSpec
from plate_env.physics.tilelink.geometry import DiscGeometry, disc_geometry, second_difference_operator
from plate_env.physics.tilelink.modal import ModalResult, modal_analysis


@dataclass(frozen=True)
class PointMassConfig:
    """Joint parameters of the point-mass model that the paper does not give (chosen, documented)."""

    k_inplane: float = 300.0  #: N/m, compression/tension and diagonal springs
    zeta_inplane: float = 0.2  #: damping ratio of a joint's two-node oscillator
    zeta_bending: float = 0.1  #: damping ratio of the first bending mode (stiffness-proportional)


@dataclass(frozen=True)
class PointMassParams:
    """Numbers the kernel needs for one object."""

    geom: DiscGeometry
    node_mass: float
    k_bending: float
    eta_bending: float  #: s, bending damping = eta * bending stiffness
    k_inplane: float
    c_inplane: float
    laplacian: np.ndarray


def linear_stiffness(geom: DiscGeometry, k_bending: float, k_inplane: float, laplacian: np.ndarray) -> np.ndarray:
    """Stiffness (3N x 3N, dofs node-major x, y, z) of the free disc linearised about its flat rest state, N/m."""
    n = geom.n_nodes
    stiff = np.kron(laplacian * k_bending, np.eye(3))
    pairs = np.vstack([geom.links, geom.diagonals])
    for a, b in pairs:
        d = np.append(geom.rest[b] - geom.rest[a], 0.0)
        e = d / np.linalg.norm(d)
        blk = k_inplane * np.outer(e, e)
        ia, ib = slice(3 * a, 3 * a + 3), slice(3 * b, 3 * b + 3)
        stiff[ia, ia] += blk
        stiff[ib, ib] += blk
        stiff[ia, ib] -= blk
        stiff[ib, ia] -= blk
    assert stiff.shape == (3 * n, 3 * n)
    return stiff


def modal(obj: ObjectSpec, k_bending: float, config: PointMassConfig = PointMassConfig()) -> ModalResult:
    """Modal analysis of the linearised point-mass disc with bending stiffness ``k_bending`` (N/m)."""
    geom = disc_geometry(obj.diameter)
    n = geom.n_nodes
    stiff = linear_stiffness(geom, k_bending, config.k_inplane, second_difference_operator(geom))
    mass = np.eye(3 * n) * (obj.mass / n)
    out_of_plane = np.zeros(3 * n, dtype=bool)
    out_of_plane[2::3] = True
    return modal_analysis(stiff, mass, out_of_plane)


def build_params(obj: ObjectSpec, config: PointMassConfig = PointMassConfig()) -> PointMassParams:
    """Set the bending stiffness so the model's first free bending eigenfrequency is ``obj.omega_n``.

    Out of plane the flat disc's stiffness is ``k_b L`` alone (in-plane springs have no transverse stiffness at
    rest), so the bending eigenfrequencies scale exactly as ``sqrt(k_b)``: one modal analysis at unit ``k_b``
    gives the factor, and a second confirms the target is hit.
    """
    geom = disc_geometry(obj.diameter)
    n = geom.n_nodes
    m = obj.mass / n
    lap = second_difference_operator(geom)
    unit = modal(obj, 1.0, config).omega_bending
    k_b = (obj.omega_n / unit) ** 2
    eta = 2.0 * config.zeta_bending / obj.omega_n
    c_in = 2.0 * config.zeta_inplane * math.sqrt(config.k_inplane * m / 2.0)
    return PointMassParams(geom=geom, node_mass=m, k_bending=k_b, eta_bending=eta, k_inplane=config.k_inplane,
                           c_inplane=c_in, laplacian=lap)


def implicit_damping_matrix(params: PointMassParams, dt: float) -> np.ndarray:
    """``(I + dt eta k_b / m L)^-1``: the bending damper integrated implicitly for one step of ``dt`` s."""
    n = params.geom.n_nodes
    a = np.eye(n) + dt * params.eta_bending * params.k_bending / params.node_mass * params.laplacian
    return np.linalg.inv(a)


#: Signs of an orbit's members (node, u-mirror, v-mirror, both) in its four parity combinations.
PARITY_SIGNS = np.array([[1, 1, 1, 1], [1, -1, 1, -1], [1, 1, -1, -1], [1, -1, -1, 1]], dtype=np.float64)


@dataclass(frozen=True)
class GridLayout:
    """The disc's nodes on the padded 8 x 8 grid of the v2 kernel (:mod:`kernels_v2`).

    ``slot`` (N,): each node's index in the padded slot array; ``masks`` (7, G): 1 where a joint leaves a slot in
    each of the four directions, where a triplet is centred in each of the two, and where a node sits; ``quad``
    (N/4, 4): the slots of each orbit of four mirror images (a node with u < 0, v < 0, its mirror in u, in v, in
    both), in the order of the damper blocks' rows.
    """

    slot: np.ndarray
    masks: np.ndarray
    quad: np.ndarray


def grid_layout(geom: DiscGeometry) -> GridLayout:
    """Place ``geom``'s nodes on the v2 kernel's grid and mark its joints, triplets and nodes there; checks that
    the joints and triplets marked are exactly ``geom``'s."""
    from plate_env.physics.tilelink import kernels_v2 as k2

    side = k2.SIDE
    cols = np.rint(geom.rest[:, 0] / geom.spacing + (side - 1) / 2).astype(np.int64)
    rows = np.rint(geom.rest[:, 1] / geom.spacing + (side - 1) / 2).astype(np.int64)
    slot = k2.PAD + side * rows + cols
    node_at = {(int(c), int(r)): k for k, (c, r) in enumerate(zip(cols, rows, strict=True))}
    masks = np.zeros((7, k2.SLOTS + 2 * k2.PAD))
    masks[k2.M_NODE, slot] = 1.0
    steps = {1: (1, 0), side: (0, 1), side + 1: (1, 1), side - 1: (-1, 1)}
    found: dict[str, set] = {"links": set(), "diagonals": set(), "triplets": set()}
    for (c, r), k in node_at.items():
        for p, o in enumerate(k2.PAIR_OFFSETS):
            dc, dr = steps[o]
            b = node_at.get((c + dc, r + dr))
            if b is None:
                continue
            cell = [node_at.get((min(c, c + dc) + ic, r + jr)) for ic in (0, 1) for jr in (0, 1)]
            if p < 2 or all(q is not None for q in cell):  # a diagonal exists where its cell's four nodes do
                masks[p, slot[k]] = 1.0
                found["links" if p < 2 else "diagonals"].add(frozenset((k, b)))
        for t, o in enumerate(k2.TRIPLET_OFFSETS):
            dc, dr = steps[o]
            a, b = node_at.get((c - dc, r - dr)), node_at.get((c + dc, r + dr))
            if a is not None and b is not None:
                masks[4 + t, slot[k]] = 1.0
                found["triplets"].add((frozenset((a, b)), k))
    assert found["links"] == {frozenset(map(int, e)) for e in geom.links}, "links do not match the grid"
    assert found["diagonals"] == {frozenset(map(int, e)) for e in geom.diagonals}, "diagonals do not match the grid"
    assert found["triplets"] == {(frozenset((int(a), int(c))), int(b)) for a, b, c in geom.triplets}, \
        "triplets do not match the grid"
    half = side // 2
    quad = [[k2.PAD + side * rr + cc for rr, cc in ((r, c), (r, side - 1 - c), (side - 1 - r, c),
                                                   (side - 1 - r, side - 1 - c))]
            for r in range(half) for c in range(half) if (c, r) in node_at]
    quad_arr = np.asarray(quad, dtype=np.int64)
    assert sorted(quad_arr.ravel().tolist()) == sorted(slot.tolist()), "the nodes are not mirror symmetric"
    return GridLayout(slot=slot, masks=masks, quad=quad_arr)


def grid_damping_blocks(params: PointMassParams, dt: float) -> np.ndarray:
    """The implicit damper ``(I + dt eta k_b / m L)^-1`` in the v2 kernel's layout (4, K, K): one block per
    parity of the grid's mirror flips over the K orbits of :attr:`GridLayout.quad`, ``[p, q, o]`` block p's
    entry (o, q).

    ``L`` commutes with both flips, so in the orthonormal basis ``1/2 sum_k s_pk e_{orbit[k]}`` of each orbit
    ``I + c L`` is block diagonal and each block is inverted on its own.
    """
    geom = params.geom
    n = geom.n_nodes
    a = np.eye(n) + dt * params.eta_bending * params.k_bending / params.node_mass * params.laplacian
    layout = grid_layout(geom)
    node_of = {int(s): k for k, s in enumerate(layout.slot)}
    blocks = np.zeros((4, len(layout.quad), len(layout.quad)))
    for p, signs in enumerate(PARITY_SIGNS):
        basis = np.zeros((n, len(layout.quad)))
        for o, members in enumerate(layout.quad):
            for sign, member in zip(signs, members, strict=True):
                basis[node_of[int(member)], o] = 0.5 * sign
        blocks[p] = np.linalg.inv(basis.T @ a @ basis).T
    return blocks
