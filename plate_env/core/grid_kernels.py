"""numba kernels for the posterior's per-probe grid arithmetic: the same floats as the numpy code they replace.

Each kernel does, element by element and in the same order, the additions, multiplications, divisions, square
roots, minima and maxima the numpy expressions do (plain IEEE-754: no fastmath, so no reassociation and no FMA
contraction), in one pass instead of one pass per numpy operation. Logarithms and exponentials are *not* taken
here: numba calls the C library's, numpy its own SIMD code, and the two differ in the last bit for ~0.2-9 % of
arguments; the callers take them with numpy between kernels. Elementwise kernels take flat (1-D, contiguous)
views of the grids. tests/test_grid_kernels.py checks every kernel
against its numpy expression bit for bit, signed zeros and NaN included.

Importing this module imports numba (~0.2 s); the kernels compile on first use (cached on disk afterwards).
:mod:`plate_env.core.jit` decides when a process loads them.
"""

from __future__ import annotations

import numba
import numpy as np

from plate_env.core import filters


def _njit(fn):
    """``numba.njit`` with numpy's error model (x / 0 is inf or NaN, as numpy gives), cached on disk where numba
    can write (else compiled per process)."""
    try:
        return numba.njit(cache=True, error_model="numpy")(fn)
    except RuntimeError:  # no writable cache location
        return numba.njit(error_model="numpy")(fn)


@_njit
def _ppoly_at(c, i, zs, out):
    """One piecewise polynomial's values at interval ``i`` (``c`` (k + 1, n_x - 1, n), ``zs`` the powers of the
    offset) into ``out`` (n), summed from the highest power's coefficient down (one pass for cubics)."""
    kk = c.shape[0]
    if kk == 4:
        c3, c2, c1, c0 = c[3, i], c[2, i], c[1, i], c[0, i]
        z1, z2, z3 = zs[1], zs[2], zs[3]
        for j in range(out.size):
            v = 0.0 + c3[j] * 1.0
            v = v + c2[j] * z1
            v = v + c1[j] * z2
            out[j] = v + c0[j] * z3
        return
    top = c[kk - 1, i]
    for j in range(out.size):
        out[j] = 0.0 + top[j] * 1.0
    for kp in range(1, kk):
        zk = zs[kp]
        b = c[kk - kp - 1, i]
        for j in range(out.size):
            out[j] = out[j] + b[j] * zk


@_njit
def ppoly3_at(cm, cs, cp, i, s, out_m, out_s, out_p):
    """Three piecewise polynomials (coefficients ``(k + 1, n_x - 1, n)``: :func:`plate_env.core.filters.ppoly_eval`'s
    with the trailing axes flattened) at one point (interval ``i``, ``s = x - x[i]``) into ``out_m``, ``out_s`` (then
    ``np.maximum(out_s, 0.0)``) and ``out_p`` (then ``np.clip(out_p, 0.0, 1.0)``), each (n). The powers of ``s``
    are ppoly_eval's (``z = z * s`` from 1)."""
    kk = cm.shape[0]
    zs = np.empty(kk)
    z = 1.0
    zs[0] = 1.0
    for kp in range(1, kk):
        z = z * s
        zs[kp] = z
    _ppoly_at(cm, i, zs, out_m)
    _ppoly_at(cs, i, zs, out_s)
    _ppoly_at(cp, i, zs, out_p)
    for j in range(out_s.size):
        vs = out_s[j]
        out_s[j] = vs if (vs > 0.0 or vs != vs) else 0.0  # np.maximum(s, 0.0): +0.0 for -0.0, NaN kept
        vp = out_p[j]
        vp = vp if (vp >= 0.0 or vp != vp) else 0.0  # np.clip(p, 0.0, 1.0): -0.0 kept, NaN kept
        out_p[j] = vp if (vp <= 1.0 or vp != vp) else 1.0


@_njit
def smoothed(p, n_repeats, out):
    """``(p * n_repeats + 0.5) / (n_repeats + 1.0)`` (:func:`plate_env.identify.inference.smoothed_p`)."""
    den = n_repeats + 1.0
    for j in range(p.size):
        out[j] = (p[j] * n_repeats + 0.5) / den


@_njit
def stable_parts(mu, spread, p, omega_b, stderr2, sigma2, n_repeats, nu, neg_p, q, var):
    """A stable probe's likelihood before its logarithms: ``neg_p = -smoothed_p(p)``, ``var = spread ** 2 +
    stderr ** 2 + sigma_model ** 2`` and ``q = (omega_b - mu) ** 2 / (nu * var)`` (``stderr2``, ``sigma2``: the
    squares, taken by the caller as Python takes them)."""
    den = n_repeats + 1.0
    for j in range(mu.size):
        neg_p[j] = -((p[j] * n_repeats + 0.5) / den)
        sp = spread[j]
        v = sp * sp + stderr2 + sigma2
        var[j] = v
        d = omega_b - mu[j]
        q[j] = d * d / (nu * v)


@_njit
def stable_combine(log_1mp, log_q, log_var, half_nu1, out):
    """``log1p(-p) + (-0.5 (nu + 1) log1p(q) - 0.5 log(var))`` from the three logarithms (``half_nu1`` =
    ``-0.5 * (nu + 1.0)``), into ``out`` (which may be ``log_1mp``)."""
    for j in range(out.size):
        out[j] = log_1mp[j] + (half_nu1 * log_q[j] - 0.5 * log_var[j])


@_njit
def check_parts(mu, spread, p, omega_b, stderr2, sigma2, n_repeats, nu, z, x, one_minus_p, ps):
    """A stable probe's predictive-check terms before their logarithms: ``z = (omega_b - mu) / sqrt(spread ** 2 +
    stderr ** 2 + sigma_model ** 2)``, ``x = z ** 2 / nu``, ``ps = smoothed_p(p)`` and ``one_minus_p = 1.0 - ps``."""
    den = n_repeats + 1.0
    for j in range(mu.size):
        sp = spread[j]
        zz = (omega_b - mu[j]) / np.sqrt(sp * sp + stderr2 + sigma2)
        z[j] = zz
        x[j] = zz * zz / nu
        pr = (p[j] * n_repeats + 0.5) / den
        ps[j] = pr
        one_minus_p[j] = 1.0 - pr


@_njit
def check_add(total, log_x, log_1mp, half_nu1, count):
    """``total += count * (0.5 (nu + 1) log1p(x) + -log(1 - p))`` (``half_nu1`` = ``0.5 * (nu + 1.0)``) for a
    stable probe's surprise (summed over its one-element last axis as numpy sums: from 0.0)."""
    c = float(count)
    for j in range(total.size):
        total[j] = total[j] + c * (0.0 + (half_nu1 * log_x[j] + -log_1mp[j]))


@_njit
def _pairwise(v, start, n):
    """numpy's pairwise sum of ``v[start:start + n]`` for ``n <= 128`` (below 8 terms one by one from 0.0, else in
    8 interleaved partial sums)."""
    if n < 8:
        res = 0.0
        for j in range(n):
            res += v[start + j]
        return res
    r0, r1, r2, r3 = v[start], v[start + 1], v[start + 2], v[start + 3]
    r4, r5, r6, r7 = v[start + 4], v[start + 5], v[start + 6], v[start + 7]
    i = 8
    while i < n - (n % 8):
        r0 += v[start + i]
        r1 += v[start + i + 1]
        r2 += v[start + i + 2]
        r3 += v[start + i + 3]
        r4 += v[start + i + 4]
        r5 += v[start + i + 5]
        r6 += v[start + i + 6]
        r7 += v[start + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += v[start + i]
        i += 1
    return res


@_njit
def replicates_at_least(u, t_part, p, flag_stable, flag_unstable, t_obs):
    """How many replicate sweeps (rows of ``u``, ``t_part``: (draws, n)) have a surprise >= ``t_obs``: per row
    ``np.where(u >= p, t_part + flag_stable, flag_unstable).sum()``, summed as numpy sums a row (n <= 128)."""
    n = u.shape[1]
    row = np.empty(n)
    count = 0
    for d in range(u.shape[0]):
        for j in range(n):
            stable = t_part[d, j] + flag_stable[j]  # both sides computed: a select, not a branch
            row[j] = stable if u[d, j] >= p[j] else flag_unstable[j]
        if _pairwise(row, 0, n) >= t_obs:
            count += 1
    return count


#: :func:`plate_env.core.filters.bspline_interval` and ``bspline_bases`` compiled (inlined where called).
_interval = numba.njit(inline="always", error_model="numpy")(filters.bspline_interval)
_bases = numba.njit(inline="always", error_model="numpy")(filters.bspline_bases)


@_njit
def spline3_point(t0, t1, t2, k0, k1, k2, c_a, c_b, c_c, x0, x1, x2):
    """Three tensor-product cubic splines sharing knots ``t0, t1, t2`` (arrays) and degrees at one point (not NaN),
    as :meth:`plate_env.surrogate.atlas._TensorSpline.bases` and ``.contract`` compute them, term by term in scipy's
    order: ``(value_a, value_b, value_c)``."""
    l0 = _interval(t0, k0, x0)
    l1 = _interval(t1, k1, x1)
    l2 = _interval(t2, k2, x2)
    b0 = _bases(t0, x0, k0, l0)
    b1 = _bases(t1, x1, k1, l1)
    b2 = _bases(t2, x2, k2, l2)
    s0, s1, s2 = l0 - k0, l1 - k1, l2 - k2
    va = 0.0
    vb = 0.0
    vc = 0.0
    for i0 in range(k0 + 1):
        w0 = b0[i0]
        for i1 in range(k1 + 1):
            f01 = 1.0 * w0 * b1[i1]
            for i2 in range(k2 + 1):
                f = f01 * b2[i2]
                va += c_a[s0 + i0, s1 + i1, s2 + i2] * f
                vb += c_b[s0 + i0, s1 + i1, s2 + i2] * f
                vc += c_c[s0 + i0, s1 + i1, s2 + i2] * f
    return va, vb, vc


@_njit
def check_add_unstable(total, log_p, count):
    """``total += count * (0.0 + -log(p))`` for an unstable probe's surprise (``log_p``: numpy's log of the smoothed
    instability share)."""
    c = float(count)
    for j in range(total.size):
        total[j] = total[j] + c * (0.0 + -log_p[j])
