"""Shared fixtures: small, fast probe settings for the default (non-slow) suite."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.identify.fitting import lorentzian
from plate_env.surrogate.atlas import Atlas, atlas_from_repeats


def pytest_configure(config) -> None:
    """The disk cache of spline coefficients (plate_env/core/cache.py) in a directory of this test session (kept out of
    the user's cache; shared by the session's worker processes), unless PLATE_ENV_CACHE_DIR is set."""
    import os
    import tempfile

    if "PLATE_ENV_CACHE_DIR" not in os.environ:
        os.environ["PLATE_ENV_CACHE_DIR"] = config._plate_env_cache = tempfile.mkdtemp(prefix="plate_env_test_cache_")


def pytest_unconfigure(config) -> None:
    import shutil

    made = getattr(config, "_plate_env_cache", None)
    if made:
        shutil.rmtree(made, ignore_errors=True)


@pytest.fixture(scope="session")
def tilelink():
    return pe.make_physics("tilelink")


@pytest.fixture(scope="session")
def cheese():
    return pe.preset("cheese")


def toy_atlas(scale: float = 1.0, unstable_above_pi: float | None = None) -> Atlas:
    """A small atlas (A_p 3 deg) whose mean is a Lorentzian with f0 rising with log omega_n, three noisy repeats.

    ``unstable_above_pi``: every repeat of objects with omega_n above this (pi rad/s) is unstable at f_p >= 26 Hz
    (p_unstable 1 there, 0 elsewhere)."""
    f = np.arange(10.0, 41.0, 2.0)
    w = np.geomspace(2, 40, 7) * math.pi
    a = np.radians([30.0, 40.0, 50.0, 60.0])
    ff, ww, aa = np.meshgrid(f, w, a, indexing="ij")
    f0 = 22 + 6 * np.log(ww / (2 * math.pi)) / np.log(20) - 4 * (aa - 0.7)
    mean = scale * lorentzian(ff, 400 + 200 * np.log(ww / math.pi) / 4, f0, 4.5)
    rng = np.random.default_rng(0)
    reps = mean[:, None, :, :, None] + rng.normal(0, 5, (*mean.shape[:1], 1, *mean.shape[1:], 3))
    mask = np.zeros(mean.shape, bool)
    if unstable_above_pi is not None:
        mask = (ff >= 26) & (ww > unstable_above_pi * math.pi)
    unstable = np.broadcast_to(mask[:, None, :, :, None], reps.shape).copy()
    return atlas_from_repeats("toy", "toy", f, [3.0], w, a, reps, np.full(reps.shape, 2.0), unstable, {"toy": True})


@pytest.fixture(name="toy_atlas")
def toy_atlas_fixture():
    """The :func:`toy_atlas` builder."""
    return toy_atlas
