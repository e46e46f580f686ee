"""The response atlas: interpolation, files, and interpolators cached on the instance."""

from __future__ import annotations

import math
import pickle

import numpy as np

from plate_env.atlas import Atlas, atlas_from_repeats
from plate_env.fitting import lorentzian
from plate_env.inference import grid_response


def toy_atlas(scale: float = 1.0) -> Atlas:
    """A small atlas whose mean is a Lorentzian with f0 rising with log omega_n, three noisy repeats."""
    f = np.arange(10.0, 41.0, 2.0)
    w = np.geomspace(2, 40, 7) * math.pi
    a = np.radians([30.0, 40.0, 50.0, 60.0])
    ff, ww, aa = np.meshgrid(f, w, a, indexing="ij")
    f0 = 22 + 6 * np.log(ww / (2 * math.pi)) / np.log(20) - 4 * (aa - 0.7)
    mean = scale * lorentzian(ff, 400 + 200 * np.log(ww / math.pi) / 4, f0, 4.5)
    rng = np.random.default_rng(0)
    reps = mean[:, None, :, :, None] + rng.normal(0, 5, (*mean.shape[:1], 1, *mean.shape[1:], 3))
    return atlas_from_repeats("toy", "toy", f, [3.0], w, a, reps, np.full(reps.shape, 2.0),
                              np.zeros(reps.shape, bool), {"toy": True})


def test_interpolators_are_cached_per_instance_not_shared():
    one, two = toy_atlas(1.0), toy_atlas(2.0)  # equal shapes and grids, different values
    m1 = one.predict(21.0, 3.0, 30.0, 0.7)[0]
    m2 = two.predict(21.0, 3.0, 30.0, 0.7)[0]
    assert 1.9 * m1 < m2 < 2.1 * m1  # a shared cache would have answered the first atlas
    assert one._interpolator("mean", 0) is one._interpolator("mean", 0)
    assert one._interpolator("mean", 0) is not two._interpolator("mean", 0)
    g = grid_response(one, 3.0, 21, 5)
    assert grid_response(one, 3.0, 21, 5) is g and grid_response(two, 3.0, 21, 5) is not g
    assert one != two and one == one  # identity equality: numpy fields have no value equality


def test_pickled_atlas_drops_its_cache_and_predicts_the_same():
    atlas = toy_atlas()
    before = atlas.predict(23.5, 3.0, 40.0, 0.8)
    grid_response(atlas, 3.0, 21, 5)(23.5)
    assert atlas._cache
    back = pickle.loads(pickle.dumps(atlas))
    assert back._cache == {}
    np.testing.assert_array_equal(back.predict(23.5, 3.0, 40.0, 0.8), before)
