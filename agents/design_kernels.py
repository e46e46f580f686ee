"""The bayes agent's inner loop, compiled: the expected-information sums of every candidate outcome.

Importing this module imports numba (~0.5 s); the first call compiles (cached on disk afterwards).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, fastmath=True)
def stable_sums(y: np.ndarray, mu: np.ndarray, s2: np.ndarray, keep_p: np.ndarray, se2: np.ndarray, sm2: float,
                moments: np.ndarray, nu: float, out: np.ndarray) -> None:
    """``out[f, w, s, q] = sum_c like[f, w, s, c] * moments[c, q]`` with the Student-t likelihood of outcome
    ``y[f, w, s]`` (deg/s) at each grid cell ``c`` of candidate ``f`` and window ``w``:
    ``like = keep_p / sqrt(var) * (1 + (y - mu)^2 / (nu var)) ** (-(nu + 1) / 2)``, ``var = s2 + se2[w] + sm2``
    (the exponential of :func:`plate_env.identify.inference.probe_log_likelihood`'s stable branch, ``keep_p`` its
    ``1 - p``). Shapes: y (F, W, S); mu, s2, keep_p (F, C); se2 (W,); moments (C, 3); out (F, W, S, 3),
    overwritten. The samples are the inner loop (contiguous: it vectorises; ``fastmath``: the compiled sums are
    deterministic on one machine, their rounding may differ on another CPU)."""
    n_f, n_w, n_s = y.shape
    n_c = mu.shape[1]
    half = -0.5 * (nu + 1.0)
    four = nu == 4.0
    a0 = np.empty(n_s)
    a1 = np.empty(n_s)
    a2 = np.empty(n_s)
    for f in range(n_f):
        for w in range(n_w):
            a0[:] = 0.0
            a1[:] = 0.0
            a2[:] = 0.0
            yy = y[f, w]
            for c in range(n_c):
                var = s2[f, c] + se2[w] + sm2
                base = keep_p[f, c] / math.sqrt(var)
                inv = 1.0 / (nu * var)
                muc = mu[f, c]
                m0, m1, m2 = moments[c, 0], moments[c, 1], moments[c, 2]
                if four:
                    for s in range(n_s):
                        r = yy[s] - muc
                        q = 1.0 + r * r * inv
                        like = base / (q * q * math.sqrt(q))
                        a0[s] += like * m0
                        a1[s] += like * m1
                        a2[s] += like * m2
                else:
                    for s in range(n_s):
                        r = yy[s] - muc
                        like = base * (1.0 + r * r * inv) ** half
                        a0[s] += like * m0
                        a1[s] += like * m1
                        a2[s] += like * m2
            for s in range(n_s):
                out[f, w, s, 0] = a0[s]
                out[f, w, s, 1] = a1[s]
                out[f, w, s, 2] = a2[s]
