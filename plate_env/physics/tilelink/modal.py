"""Modal analysis of the linearised free disc: the first non-rigid bending eigenfrequency omega_n.

Pure numpy/scipy, shared by every tile-link model: a model provides its linearised stiffness ``K`` and mass
``M`` about the flat rest state (no gravity, no contact) and which degrees of freedom are out-of-plane; this
module counts the zero modes (rigid motions and the free twist) with an absolute threshold and returns the
lowest remaining mode whose shape is mostly out-of-plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg


@dataclass(frozen=True)
class ModalResult:
    """Eigenfrequencies (rad/s, ascending), how many are zero modes, and the first bending mode."""

    omegas: np.ndarray
    n_zero: int
    omega_bending: float


def modal_analysis(stiffness: np.ndarray, mass: np.ndarray, out_of_plane: np.ndarray,
                   zero_tol: float = 1e-2) -> ModalResult:
    """Solve ``K phi = w^2 M phi`` and pick the first non-zero mode with > 50 % of its energy out-of-plane.

    ``zero_tol`` is absolute on ``w`` in rad/s: modes slower than that are counted as zero modes (rigid motions,
    the free twist). A relative threshold misclassifies the softest objects, so it is absolute.
    """
    evals, evecs = scipy.linalg.eigh(stiffness, mass)
    omegas = np.sqrt(np.clip(evals, 0.0, None))
    n_zero = int(np.sum(omegas < zero_tol))
    for idx in range(n_zero, len(omegas)):
        vec = evecs[:, idx]
        energy = vec * (mass @ vec)
        if energy[out_of_plane].sum() > 0.5 * energy.sum():
            return ModalResult(omegas=omegas, n_zero=n_zero, omega_bending=float(omegas[idx]))
    raise ValueError("the linearised model has no out-of-plane (bending) mode")
