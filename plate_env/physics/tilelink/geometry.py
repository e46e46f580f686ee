"""Geometry of the paper's tile-link disc: 52 tiles on a square grid inside a circle, 88 joint units.

The paper's 80 mm disc is covered by 52 virtual tiles of 10 mm (rows of 4, 6, 8, 8, 8, 8, 6, 4 tiles); adjacent
tiles are connected by 88 viscoelastic joint units. For another diameter the grid spacing scales as
``diameter / 8``. Everything here is pure numpy and computed once per diameter.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from plate_env.core.setup import PAPER_SETUP

GRID_CELLS_ACROSS = 8


@dataclass(frozen=True)
class DiscGeometry:
    """Rest geometry of the tile-link disc (plate frame, metres).

    Attributes:
        spacing: tile size / grid spacing, m.
        rest: (N, 2) tile centres relative to the disc centre, m.
        links: (88, 2) node index pairs of the joint units (4-neighbours).
        link_dir: (88,) 0 for a joint between horizontal (u) neighbours, 1 for vertical (v) neighbours.
        triplets: (T, 3) collinear neighbour triplets (a, b, c), b in the middle, along rows and columns.
        cells: (C, 4) 2x2 groups of tiles (a, b, c, d) counter-clockwise: (i,j), (i+1,j), (i+1,j+1), (i,j+1).
        diagonals: (2C, 2) node pairs across the cells' diagonals.
    """

    spacing: float
    rest: np.ndarray
    links: np.ndarray
    link_dir: np.ndarray
    triplets: np.ndarray
    cells: np.ndarray
    diagonals: np.ndarray

    @property
    def n_nodes(self) -> int:
        return int(self.rest.shape[0])


@lru_cache(maxsize=8)
def disc_geometry(diameter: float = PAPER_SETUP.diameter) -> DiscGeometry:
    """Tile centres on a ``diameter/8`` grid whose centres lie inside the disc, and their connectivity."""
    h = diameter / GRID_CELLS_ACROSS
    radius = diameter / 2
    index: dict[tuple[int, int], int] = {}
    rest = []
    for j in range(GRID_CELLS_ACROSS):
        for i in range(GRID_CELLS_ACROSS):
            u, v = (i - 3.5) * h, (j - 3.5) * h
            if u * u + v * v <= radius * radius * (1 + 1e-9):
                index[(i, j)] = len(rest)
                rest.append((u, v))
    links, link_dir, triplets, cells, diagonals = [], [], [], [], []
    for (i, j), k in index.items():
        for d, (di, dj) in enumerate(((1, 0), (0, 1))):
            nb = index.get((i + di, j + dj))
            if nb is not None:
                links.append((k, nb))
                link_dir.append(d)
            prev = index.get((i - di, j - dj))
            if nb is not None and prev is not None:
                triplets.append((prev, k, nb))
        quad = [index.get(q) for q in ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1))]
        if all(q is not None for q in quad):
            cells.append(quad)
            diagonals.append((quad[0], quad[2]))
            diagonals.append((quad[1], quad[3]))
    return DiscGeometry(
        spacing=h,
        rest=np.asarray(rest, dtype=np.float64),
        links=np.asarray(links, dtype=np.int64),
        link_dir=np.asarray(link_dir, dtype=np.int64),
        triplets=np.asarray(triplets, dtype=np.int64),
        cells=np.asarray(cells, dtype=np.int64),
        diagonals=np.asarray(diagonals, dtype=np.int64),
    )


def second_difference_operator(geom: DiscGeometry) -> np.ndarray:
    """``L = sum_t b_t b_t^T`` with ``b_t = e_a - 2 e_b + e_c`` over the row/column triplets (N x N).

    ``0.5 * k_b * x^T L x`` is the discrete-curvature bending energy of one coordinate.
    """
    n = geom.n_nodes
    lap = np.zeros((n, n))
    for a, b, c in geom.triplets:
        vec = np.zeros(n)
        vec[a], vec[b], vec[c] = 1.0, -2.0, 1.0
        lap += np.outer(vec, vec)
    return lap
