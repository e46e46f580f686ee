"""numpy versions of the few scipy routines an identification uses, computing the same floats in the same order.

``plate-env fit`` and an episode's estimate spend a fraction of a second on the posterior, but importing
``scipy.ndimage``, ``scipy.signal`` and ``scipy.interpolate`` costs 1-3 s on a loaded machine (issue 25). Each
function here reproduces one scipy routine *bit for bit* for the arguments the package passes (float64 arrays;
tests/test_filters.py compares them with scipy), so the numbers a fit or a leaderboard prints do not change:

- :func:`gaussian_filter1d`: ``scipy.ndimage.gaussian_filter1d`` (order 0, modes ``"constant"`` and ``"nearest"``):
  the same kernel, then the symmetric correlation of ``NI_Correlate1D`` (centre term first, then the pairs from the
  outermost in).
- :func:`minimum_filter1d`: ``scipy.ndimage.minimum_filter1d`` (mode ``"nearest"``, origin 0).
- :func:`fftconvolve_same`: ``scipy.signal.fftconvolve(a, kernel, mode="same", axes=0)`` for real input: the same
  5-smooth transform length, numpy's pocketfft (the same library scipy.fft wraps).
- :func:`ppoly_eval`: ``scipy.interpolate.PPoly(c, x, extrapolate=True)(xval)``: the interval search and the
  power sum of ``_ppoly.evaluate_poly1``.
- :func:`bspline_interval`, :func:`bspline_bases`: ``fitpack``'s interval search and de Boor's recursion, the
  B-spline bases of ``scipy.interpolate.NdBSpline`` at one point (plain Python; numba compiles the same functions
  for :mod:`plate_env.core.grid_kernels`).
"""

from __future__ import annotations

import math

import numpy as np

_PAD_MODES = {"constant": "constant", "nearest": "edge"}


def _gaussian_kernel(sigma: float, radius: int) -> np.ndarray:
    """``scipy.ndimage._filters._gaussian_kernel1d(sigma, 0, radius)``."""
    sigma2 = sigma * sigma
    x = np.arange(-radius, radius + 1)
    phi_x = np.exp(-0.5 / sigma2 * x ** 2)
    return phi_x / phi_x.sum()


def gaussian_filter1d(a: np.ndarray, sigma: float, axis: int = -1, mode: str = "constant", cval: float = 0.0,
                      truncate: float = 4.0) -> np.ndarray:
    """A Gaussian filter of scale ``sigma`` samples along ``axis`` (order 0); outside the array: ``cval``
    (``mode="constant"``) or the edge value (``"nearest"``). Returns a new float64 array."""
    if mode not in _PAD_MODES:
        raise ValueError(f"mode = {mode!r}: only {sorted(_PAD_MODES)}")
    a = np.asarray(a, dtype=np.float64)
    radius = int(truncate * float(sigma) + 0.5)
    w = _gaussian_kernel(sigma, radius)[::-1]  # as scipy: correlate with the reversed (symmetric) kernel
    if not np.array_equal(w, w[::-1]):  # scipy's symmetric branch applies only to an exactly symmetric kernel
        raise ArithmeticError("gaussian kernel not symmetric")
    x = np.moveaxis(a, axis, 0)
    if mode == "constant" and cval == 0.0 and x.size and np.all(x >= 0.0):
        # zeros in, +0.0 out: only the rows within ``radius`` of a non-zero one need the loop (every term left out
        # adds +0.0 to a sum >= +0.0: the same floats)
        rows = np.flatnonzero(x.reshape(x.shape[0], -1).any(axis=1))
        out = np.zeros(x.shape)
        if rows.size:
            lo, hi = max(int(rows[0]) - radius, 0), min(int(rows[-1]) + radius + 1, x.shape[0])
            out[lo:hi] = _correlate_symmetric(x[max(lo - radius, 0):hi + radius], w, radius, "constant", cval,
                                              lo - max(lo - radius, 0), hi - lo)
        return np.moveaxis(out, 0, axis)
    return np.ascontiguousarray(np.moveaxis(_correlate_symmetric(x, w, radius, mode, cval, 0, x.shape[0]), 0, axis))


def _correlate_symmetric(x: np.ndarray, w: np.ndarray, radius: int, mode: str, cval: float, start: int,
                         n: int) -> np.ndarray:
    """Rows ``start .. start + n`` of the correlation of ``x`` (axis 0, padded by ``mode``) with the symmetric
    kernel ``w`` (length ``2 radius + 1``), summed as NI_Correlate1D's symmetric loop sums them: the centre term,
    then ``(left + right) * w`` from the outermost pair in."""
    pad = [(radius, radius)] + [(0, 0)] * (x.ndim - 1)
    xp = np.pad(x, pad, mode=_PAD_MODES[mode], **({"constant_values": cval} if mode == "constant" else {}))
    c = radius + start
    out = xp[c:c + n] * w[radius]
    buf = np.empty_like(out)
    for j in range(radius, 0, -1):  # jj = -size1 .. -1
        np.add(xp[c - j:c - j + n], xp[c + j:c + j + n], out=buf)
        buf *= w[radius - j]
        out += buf
    return out


def minimum_filter1d(a: np.ndarray, size: int, axis: int = -1) -> np.ndarray:
    """The minimum over a window of ``size`` samples centred on each (origin 0: ``size // 2`` before), the edge
    value repeated beyond the ends (``scipy.ndimage.minimum_filter1d(mode="nearest")``)."""
    if size < 1:
        raise ValueError(f"size = {size!r} must be >= 1")
    a = np.asarray(a)
    x = np.moveaxis(a, axis, 0)
    n = x.shape[0]
    before, after = size // 2, size - 1 - size // 2
    xp = np.pad(x, [(before, after)] + [(0, 0)] * (x.ndim - 1), mode="edge")
    out = xp[0:n].copy()
    for j in range(1, size):
        np.minimum(out, xp[j:j + n], out=out)
    return np.ascontiguousarray(np.moveaxis(out, 0, axis))


def next_fast_len_real(target: int) -> int:
    """The smallest 5-smooth integer (2^a 3^b 5^c) >= ``target``: ``scipy.fft.next_fast_len(target, real=True)``."""
    if target <= 6:
        return max(int(target), 1)
    best = 1 << (int(target) - 1).bit_length()  # a power of 2 >= target
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            n = p35  # the smallest p35 * 2^k >= target
            if n < target:
                n <<= (math.ceil(target / n) - 1).bit_length()
            best = min(best, n)
            p35 *= 3
        p5 *= 5
    return best


def fftconvolve_same(a: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``scipy.signal.fftconvolve(a, kernel, mode="same", axes=0)`` for real float64 ``a`` and a real ``kernel``
    along axis 0 (``kernel`` broadcast over the other axes, e.g. shape ``(k, 1)``)."""
    a = np.asarray(a, dtype=np.float64)
    kernel = np.asarray(kernel, dtype=np.float64)
    s1, s2 = a.shape[0], kernel.shape[0]
    if s1 == 1 or s2 == 1:  # scipy drops an axis of length 1 from the transform: a plain product
        return a * kernel
    full = s1 + s2 - 1
    n = next_fast_len_real(full)
    sp = np.fft.rfft(a, n, axis=0) * np.fft.rfft(kernel, n, axis=0)
    ret = np.fft.irfft(sp, n, axis=0)[:full]
    start = (full - s1) // 2
    return ret[start:start + s1]


def ppoly_eval(c: np.ndarray, x: np.ndarray, xval: float) -> np.ndarray:
    """A piecewise cubic (or any degree) polynomial, coefficients ``c`` of shape ``(k + 1, len(x) - 1, ...)`` (highest
    power first, in powers of ``xval - x[i]``), at one point, extrapolated from the first / last piece outside
    ``x`` (ascending): ``PPoly.construct_fast(c, x, extrapolate=True)(xval)``. NaN gives NaN."""
    xval = float(xval)
    if xval != xval:
        return np.full(c.shape[2:], np.nan)
    i, s = ppoly_interval(x, xval)
    res = 0.0 + c[-1, i] * 1.0
    z = 1.0
    for kp in range(1, c.shape[0]):  # evaluate_poly1: res += c[k-kp] z; z *= s (z = s^kp)
        z = z * s
        res = res + c[c.shape[0] - kp - 1, i] * z
    return res


def ppoly_interval(x: np.ndarray, xval: float) -> tuple[int, float]:
    """:func:`ppoly_eval`'s piece ``i`` for ``xval`` (not NaN) and the offset ``xval - x[i]`` its powers take."""
    i = int(np.searchsorted(x, xval, side="right")) - 1
    i = min(max(i, 0), len(x) - 2)
    return i, xval - float(x[i])


def bspline_interval(t: list[float], k: int, x: float) -> int:
    """A B-spline's knot interval: ``l`` with ``t[l] <= x < t[l + 1]`` (``k <= l < n``; x at the last knot:
    ``n - 1``), as scipy's ``fitpack::_find_interval`` from ``prev_l = k``."""
    n = len(t) - k - 1
    if x != x:
        return -1
    ell = k + 1
    while x >= t[ell] and ell != n:
        ell += 1
    return ell - 1


def bspline_bases(t: list[float], x: float, k: int, ell: int) -> list[float]:
    """The ``k + 1`` non-zero B-splines at ``x`` in the interval ``ell``, as scipy's ``fitpack::_deBoor_D``
    (``m = 0``) computes them."""
    h = [1.0] + [0.0] * k
    for j in range(1, k + 1):
        hh = h[:j]
        h[0] = 0.0
        for n in range(1, j + 1):
            ind = ell + n
            xb, xa = t[ind], t[ind - j]
            if xb == xa:
                h[n] = 0.0
                continue
            w = hh[n - 1] / (xb - xa)
            h[n - 1] += w * (xb - x)
            h[n] = w * (x - xa)
    return h
