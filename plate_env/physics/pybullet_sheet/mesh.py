"""A thin two-layer tetrahedral disc mesh with about equal area per node (SI units, pure numpy/scipy).

PyBullet gives every soft-body node the same mass (total mass / node count), so the mesh must give every node
about the same share of the disc's area, otherwise the rotational inertia is wrong. The in-plane points follow
the "sunflower with an even boundary" layout: ``n - b`` interior points on a Vogel spiral at radii
``R sqrt((i - 1/2) / (n - (b + 1)/2))`` and ``b = round(2 sqrt(n))`` points on the rim. The 2D Delaunay triangles
are extruded into prisms (bottom layer at ``z = 0``, top layer at ``z = thickness``) and each prism is split into
three tetrahedra with the diagonal rule "lower global index on the bottom to higher on the top", which makes the
split of every shared quad face agree between neighbouring prisms (a conforming mesh).
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass

import numpy as np

GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


@dataclass(frozen=True)
class SheetMesh:
    """A two-layer tetrahedral sheet.

    Attributes:
        nodes: (N, 3) node positions, m; bottom layer first (``n_layer`` nodes at z = 0), then the top layer.
        tets: (M, 4) node indices of the tetrahedra, positively oriented.
        n_layer: nodes per layer.
        radius: disc radius, m (the rim nodes lie on it).
        thickness: distance between the layers, m.
    """

    nodes: np.ndarray
    tets: np.ndarray
    n_layer: int
    radius: float
    thickness: float

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)


def sunflower_points(n: int, radius: float, rim_factor: float = 2.0) -> np.ndarray:
    """(n, 2) points of equal area in a disc of ``radius`` (m): a Vogel spiral plus one rim ring.

    Point ``i`` (1-based) stands for the ``i``-th equal-area annulus: interior points at ``R sqrt((i - 1/2)/n)``
    on the golden-angle spiral, the last ``b = round(rim_factor sqrt(n))`` points on one ring whose radius keeps
    their mean ``r^2``. Then the point set has exactly the polar moment ``n <r^2> = n R^2 / 2`` of a uniform disc
    of radius ``R``: with equal node masses the sheet's rotational inertia about its normal is the disc's.
    The rim ring sits about half a node spacing inside ``R`` (the collision margin adds a little).
    """
    if n < 8:
        raise ValueError(f"need at least 8 points per layer, got {n}")
    b = int(round(rim_factor * math.sqrt(n)))
    n_in = n - b
    i = np.arange(1, n_in + 1, dtype=float)
    r = np.sqrt((i - 0.5) / n)
    th = i * GOLDEN_ANGLE
    inner = np.column_stack([r * np.cos(th), r * np.sin(th)])
    r_rim = math.sqrt(float(np.mean((np.arange(n_in + 1, n + 1) - 0.5) / n)))
    tb = 2.0 * math.pi * np.arange(b) / b
    rim = r_rim * np.column_stack([np.cos(tb), np.sin(tb)])
    return radius * np.concatenate([inner, rim])


def delaunay_triangles(pts: np.ndarray) -> np.ndarray:
    """``scipy.spatial.Delaunay(pts).simplices`` (a copy), kept in the disk cache (:mod:`plate_env.core.cache`,
    keyed by the points' bytes): a process that builds a scene does not import scipy.spatial (1-2 s on a loaded
    machine) once the triangulation of these points has been computed on the machine."""
    from plate_env.core.cache import cached_arrays, content_key

    def build() -> dict[str, np.ndarray]:
        from scipy.spatial import Delaunay

        return {"simplices": Delaunay(pts).simplices.copy()}

    return np.array(cached_arrays("delaunay", content_key("delaunay", np.asarray(pts, float)), build)["simplices"])


def make_sheet(n_layer: int, diameter: float, thickness: float) -> SheetMesh:
    """Build the two-layer sheet: ``n_layer`` points per layer, disc ``diameter`` (m), layer gap ``thickness`` (m)."""
    if not (diameter > 0 and thickness > 0):
        raise ValueError("diameter and thickness must be positive")
    radius = diameter / 2.0
    pts = sunflower_points(n_layer, radius)
    tri = delaunay_triangles(pts)
    # drop slivers on the rim (Delaunay can make near-zero-area triangles between rim points)
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    tri = tri[area > 1e-3 * np.median(area)]
    tri.sort(axis=1)  # a < b < c
    n = n_layer
    bottom = np.column_stack([pts, np.zeros(n)])
    top = np.column_stack([pts, np.full(n, thickness)])
    nodes = np.concatenate([bottom, top])
    ta, tb, tc = tri[:, 0], tri[:, 1], tri[:, 2]
    tets = np.concatenate([
        np.column_stack([ta, tb, tc, tc + n]),
        np.column_stack([ta, tb, tb + n, tc + n]),
        np.column_stack([ta, ta + n, tb + n, tc + n]),
    ])
    # orient every tetrahedron positively
    p = nodes[tets]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    neg = vol < 0
    tets[neg] = tets[neg][:, [1, 0, 2, 3]]
    return SheetMesh(nodes=nodes, tets=tets.astype(np.int64), n_layer=n, radius=radius, thickness=thickness)


def vtk_text(mesh: SheetMesh, origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> str:
    """The mesh as a legacy ASCII VTK unstructured grid (what ``loadSoftBody`` reads for tetrahedra)."""
    pts = mesh.nodes + np.asarray(origin)
    lines = ["# vtk DataFile Version 2.0", "plate_env sheet", "ASCII", "DATASET UNSTRUCTURED_GRID",
             f"POINTS {len(pts)} double"]
    lines += [f"{x:.9g} {y:.9g} {z:.9g}" for x, y, z in pts]
    lines.append(f"CELLS {len(mesh.tets)} {5 * len(mesh.tets)}")
    lines += [f"4 {a} {b} {c} {d}" for a, b, c, d in mesh.tets]
    lines.append(f"CELL_TYPES {len(mesh.tets)}")
    lines += ["10"] * len(mesh.tets)
    return "\n".join(lines) + "\n"


def write_temp_vtk(mesh: SheetMesh) -> str:
    """Write the mesh to a fresh per-process temporary ``.vtk`` file and return its path (caller removes it)."""
    fd, path = tempfile.mkstemp(prefix=f"plate_env_sheet_{os.getpid()}_", suffix=".vtk")
    with os.fdopen(fd, "w") as fh:
        fh.write(vtk_text(mesh))
    return path
