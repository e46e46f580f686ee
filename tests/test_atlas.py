"""The response atlas: interpolation, files, and interpolators cached on the instance."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from plate_env.atlas import Atlas
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


def test_atlas_interpolation_exact_at_grid_points_and_round_trip(toy_atlas, tmp_path):
    atlas = toy_atlas()
    i, k, j = 5, 3, 2
    mean, spread, pu = atlas.predict(atlas.f_hz[i], 3.0, atlas.omega_n[k], atlas.alpha[j])
    assert mean == pytest.approx(atlas.mean[i, 0, k, j], rel=1e-12)
    assert spread == pytest.approx(atlas.spread[i, 0, k, j], rel=1e-12)
    path = tmp_path / "atlas.npz"
    atlas.save(path)
    back = Atlas.load(path)
    np.testing.assert_allclose(back.mean, atlas.mean, rtol=1e-6)
    assert back.provenance == {"toy": True}
    with pytest.raises(ValueError, match="not in this atlas"):
        atlas.predict(20.0, 12.0, 30.0, 0.7)
