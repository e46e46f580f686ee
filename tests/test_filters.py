"""plate_env.core.filters: numpy versions of the scipy routines an identification uses, equal to scipy's bit for bit
(so a fit's and a leaderboard's numbers do not change), and a fit that no longer imports scipy's heavy submodules."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy import fft, ndimage, signal
from scipy.interpolate import CubicSpline, PPoly

from plate_env.core import filters as F


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal floats, signs of zeros included."""
    return a.shape == b.shape and np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b))


@pytest.mark.parametrize("mode, truncate", [("constant", 5.0), ("nearest", 4.0)])
def test_gaussian_filter1d_is_scipys_bit_for_bit(mode, truncate):
    rng = np.random.default_rng(0)
    for _ in range(60):
        n, m = int(rng.integers(1, 350)), int(rng.integers(1, 33))
        a = np.exp(3.0 * rng.normal(size=(n, m)))
        if rng.random() < 0.5:  # rows of exact zeros (a likelihood outside a member's range): the banded path
            lo, hi = sorted(int(x) for x in rng.integers(0, n + 1, 2))
            a[:lo], a[hi:] = 0.0, 0.0
        if rng.random() < 0.2:  # negative values: the general path
            a -= 1.0
        sigma = float(rng.uniform(0.3, 30.0))
        for axis, b in ((0, a), (-2, a[None]), (1, np.ascontiguousarray(a.T))):
            want = ndimage.gaussian_filter1d(b, sigma, axis=axis, mode=mode, cval=0.0, truncate=truncate)
            assert _same(F.gaussian_filter1d(b, sigma, axis=axis, mode=mode, truncate=truncate), want)
    assert _same(F.gaussian_filter1d(np.zeros((5, 3)), 2.0, axis=0), np.zeros((5, 3)))


def test_gaussian_filter1d_refuses_other_modes():
    with pytest.raises(ValueError, match="reflect"):
        F.gaussian_filter1d(np.ones(4), 1.0, mode="reflect")


def test_minimum_filter1d_is_scipys():
    rng = np.random.default_rng(1)
    for _ in range(60):
        n, m, size = int(rng.integers(1, 200)), int(rng.integers(1, 9)), int(rng.integers(1, 30))
        a = rng.normal(size=(n, m))
        for axis in (0, 1):
            assert _same(F.minimum_filter1d(a, size, axis=axis),
                         ndimage.minimum_filter1d(a, size, axis=axis, mode="nearest"))


def test_next_fast_len_and_fftconvolve_same_are_scipys_bit_for_bit():
    assert [F.next_fast_len_real(t) for t in range(1, 3000)] == [fft.next_fast_len(t, True) for t in range(1, 3000)]
    rng = np.random.default_rng(2)
    for _ in range(80):
        n, m = int(rng.integers(1, 400)), int(rng.integers(1, 9))
        half = int(rng.integers(0, n + 3))
        a, kernel = rng.random((n, m)), rng.random(2 * half + 1).reshape(-1, 1)
        assert _same(F.fftconvolve_same(a, kernel), signal.fftconvolve(a, kernel, mode="same", axes=0))


def test_ppoly_eval_is_scipys_bit_for_bit_inside_outside_and_at_the_nodes():
    rng = np.random.default_rng(3)
    for _ in range(40):
        x = np.sort(rng.uniform(0.0, 30.0, int(rng.integers(2, 20))))
        spline = CubicSpline(x, rng.normal(size=(len(x), 7, 5)), axis=0)
        pp = PPoly.construct_fast(np.ascontiguousarray(spline.c), x, True, 0)
        for xv in [*rng.uniform(-5.0, 35.0, 12), *x]:
            assert _same(F.ppoly_eval(spline.c, x, float(xv)), pp(float(xv)))
    assert np.all(np.isnan(F.ppoly_eval(spline.c, x, float("nan"))))


def test_a_fit_with_a_warm_cache_imports_no_heavy_scipy_module(tmp_path):
    """The fit's posterior and predictive check run on numpy (the two scipy-only constants come from the disk cache
    after the first fit): scipy.stats / signal / ndimage / interpolate cost 1-3 s of import on a loaded machine."""
    csv = tmp_path / "sweep.csv"
    csv.write_text("f_p_hz,a_p_deg,omega_b_deg_s,stderr_deg_s,unstable\n" + "".join(
        f"{f},3,{w},1.0,0\n" for f, w in [(12, 8.1), (16, 17.9), (20, 41.2), (24, 48.3), (26, 30.1)]))
    code = ("import runpy, sys, json; sys.argv = ['plate-env', 'fit', sys.argv[1], '--forward', sys.argv[2], "
            "'--json']\ntry:\n    runpy.run_module('plate_env', run_name='__main__')\nexcept SystemExit:\n    pass\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[:2] in "
            "(['scipy', 'stats'], ['scipy', 'signal'], ['scipy', 'ndimage'], ['scipy', 'interpolate'], "
            "['scipy', 'special']))))")
    env = dict(os.environ, PLATE_ENV_CACHE_DIR=str(tmp_path / "cache"))
    for forward in ("tilelink/pointmass", "lab"):
        runs = [subprocess.run([sys.executable, "-c", code, str(csv), forward], capture_output=True, text=True,
                               env=env, timeout=600) for _ in range(2)]
        first, second = (json.loads(r.stdout.strip().splitlines()[-1]) for r in runs)
        fits = [json.loads(r.stdout.strip().splitlines()[-2]) for r in runs]
        assert fits[0] == fits[1] and "omega_n_rad_s" in fits[0]  # the cached constants give the same numbers
        assert first, "a cold cache computes the constants with scipy"
        assert second == [], f"a warm fit imported {second}"
