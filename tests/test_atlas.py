"""The response atlas: interpolation, files, and interpolators cached on the instance."""

from __future__ import annotations

import pickle

import numpy as np

from plate_env.inference import grid_response


def test_interpolators_are_cached_per_instance_not_shared(toy_atlas):
    one, two = toy_atlas(1.0), toy_atlas(2.0)  # equal shapes and grids, different values
    m1 = one.predict(21.0, 3.0, 30.0, 0.7)[0]
    m2 = two.predict(21.0, 3.0, 30.0, 0.7)[0]
    assert 1.9 * m1 < m2 < 2.1 * m1  # a shared cache would have answered the first atlas
    assert one._interpolator("mean", 0) is one._interpolator("mean", 0)
    assert one._interpolator("mean", 0) is not two._interpolator("mean", 0)
    g = grid_response(one, 3.0, 21, 5)
    assert grid_response(one, 3.0, 21, 5) is g and grid_response(two, 3.0, 21, 5) is not g
    assert one != two and one == one  # identity equality: numpy fields have no value equality


def test_pickled_atlas_drops_its_cache_and_predicts_the_same(toy_atlas):
    atlas = toy_atlas()
    before = atlas.predict(23.5, 3.0, 40.0, 0.8)
    grid_response(atlas, 3.0, 21, 5)(23.5)
    assert atlas._cache
    back = pickle.loads(pickle.dumps(atlas))
    assert back._cache == {}
    np.testing.assert_array_equal(back.predict(23.5, 3.0, 40.0, 0.8), before)
