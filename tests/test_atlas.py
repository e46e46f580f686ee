"""The response atlas: interpolation, files, and interpolators cached on the instance."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from plate_env.identify.forward import Member
from plate_env.identify.inference import member_response
from plate_env.surrogate.atlas import Atlas


def test_interpolators_are_cached_per_instance_not_shared(toy_atlas):
    one, two = toy_atlas(1.0), toy_atlas(2.0)  # equal shapes and grids, different values
    m1 = one.predict(21.0, 3.0, 30.0, 0.7)[0]
    m2 = two.predict(21.0, 3.0, 30.0, 0.7)[0]
    assert 1.9 * m1 < m2 < 2.1 * m1  # a shared cache would have answered the first atlas
    assert one._interpolator("mean", 0) is one._interpolator("mean", 0)
    assert one._interpolator("mean", 0) is not two._interpolator("mean", 0)
    w, a = np.geomspace(10.0, 100.0, 21), np.linspace(0.6, 1.0, 5)
    g = member_response(Member(one, 1.0), 3.0, w, a)
    assert member_response(Member(one, 2.0), 3.0, w, a) is g and member_response(Member(two, 1.0), 3.0, w, a) is not g
    assert one != two and one == one  # identity equality: numpy fields have no value equality


def test_pickled_atlas_drops_its_cache_and_predicts_the_same(toy_atlas):
    atlas = toy_atlas()
    before = atlas.predict(23.5, 3.0, 40.0, 0.8)
    member_response(Member(atlas, 1.0), 3.0, np.geomspace(10.0, 100.0, 21), np.linspace(0.6, 1.0, 5))[0](23.5)
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


def test_resampled_atlas_is_exact_at_its_own_nodes_and_follows_its_spline_between(toy_atlas):
    atlas = toy_atlas()
    mid = np.sqrt(atlas.omega_n[2] * atlas.omega_n[3])
    nodes = np.sort(np.append(atlas.omega_n, mid))
    fine = atlas.resampled(nodes)
    np.testing.assert_allclose(fine.mean[:, :, np.isin(nodes, atlas.omega_n)], atlas.mean, atol=1e-6)
    f, a = atlas.f_hz[4], atlas.alpha[1]
    k = int(np.flatnonzero(nodes == mid)[0])
    assert fine.mean[4, 0, k, 1] == pytest.approx(float(atlas.predict(f, 3.0, mid, a)[0]), abs=1e-9)
    assert "resampled" in fine.provenance
    with pytest.raises(ValueError, match="omega_n nodes must increase within"):
        atlas.resampled(np.append(atlas.omega_n, atlas.omega_n[-1] * 1.5))


def test_mass_interpolation_between_atlases_on_different_omega_nodes(toy_atlas):
    """A refined atlas at one mass and a coarse one at another: conditioning between them reads both on the union
    of their omega_n nodes, each from its own spline, and interpolates in log mass there."""
    import dataclasses
    import math

    from plate_env.surrogate.conditioning import KnownInputs, condition

    coarse = dataclasses.replace(toy_atlas(1.0), provenance={"mass_g": 8.0})
    base = toy_atlas(2.0)
    mid = np.sqrt(base.omega_n[2] * base.omega_n[3])
    fine = dataclasses.replace(base.resampled(np.sort(np.append(base.omega_n, mid))), provenance={"mass_g": 16.0})
    out = condition([fine, coarse], KnownInputs(mass=0.0113))
    assert out.omega_n.size == coarse.omega_n.size + 1
    t = math.log(11.3 / 8.0) / math.log(16.0 / 8.0)
    want = (1 - t) * coarse.resampled(fine.omega_n).mean + t * fine.mean
    np.testing.assert_allclose(out.mean, want, rtol=1e-9)
    # the refined node carries the coarse atlas's spline there, not a copy of a neighbour
    k = int(np.flatnonzero(np.isclose(out.omega_n, mid))[0])
    assert out.mean[4, 0, k, 1] == pytest.approx((1 - t) * float(coarse.predict(coarse.f_hz[4], 3.0, mid,
                                                                               coarse.alpha[1])[0])
                                                 + t * fine.mean[4, 0, k, 1], rel=1e-9)
    short = dataclasses.replace(coarse.resampled(coarse.omega_n[:-1]), provenance={"mass_g": 8.0})
    with pytest.raises(ValueError, match="different omega_n ranges"):
        condition([fine, short], KnownInputs(mass=0.0113))


def test_a_shipped_forward_model_between_masses_is_conditioned_once_per_inputs():
    """An interpolated atlas is a new instance (its interpolators are built on it): loading the same forward model
    at the same known inputs again reuses it, and other inputs get their own."""
    from plate_env.identify.forward import load_forward_model
    from plate_env.surrogate.atlas import load_atlas_file
    from plate_env.surrogate.conditioning import KnownInputs

    a = load_forward_model("tilelink/pointmass", KnownInputs(mass=0.011)).members[0].atlas
    b = load_forward_model("tilelink/pointmass", KnownInputs(mass=0.011)).members[0].atlas
    c = load_forward_model("tilelink/pointmass", KnownInputs(mass=0.012)).members[0].atlas
    assert a is b and c is not a
    assert "interpolated" in a.provenance and a.provenance["mass_g"] == pytest.approx(11.0)
    nominal = load_atlas_file("atlas_tilelink_pointmass.npz")
    assert a.omega_n.size == nominal.omega_n.size  # the 8.2 g atlas read on the nominal atlas's refined nodes


def test_point_spline_equals_scipys_ndbspline_bit_for_bit():
    """The Python evaluation of an atlas spline at a few points (an env's probe, without importing scipy) gives the
    same floats as scipy's NdBSpline, inside the grid, on its nodes and at its edges."""
    import math

    from scipy.interpolate import NdBSpline

    from plate_env.surrogate.atlas import load_atlas_file

    atlas = load_atlas_file("atlas_tilelink_rigid_limit_f2.npz")
    rng = np.random.default_rng(3)
    n = 400
    for kind in ("mean", "spread", "p_unstable"):
        spline = atlas._interpolator(kind, 0)
        pts = np.stack([rng.uniform(atlas.f_hz[0], atlas.f_hz[-1], n),
                        rng.uniform(math.log(atlas.omega_n[0]), math.log(atlas.omega_n[-1]), n),
                        rng.uniform(atlas.alpha[0], atlas.alpha[-1], n)], -1)
        nodes = np.array(np.meshgrid(atlas.f_hz, np.log(atlas.omega_n)[[0, 1, -1]], atlas.alpha[[0, -1]],
                                     indexing="ij")).reshape(3, -1).T
        pts = np.concatenate([pts, nodes])
        want = NdBSpline(spline.t, spline.c, spline.k)(pts)
        got = np.array([spline.at(p) for p in pts.tolist()])  # the Python path (before scipy is imported)
        assert np.array_equal(got, want)
        assert np.array_equal(spline(pts[:4]), want[:4]) and np.array_equal(spline(pts), want)  # scipy's


def test_predict_point_gives_predicts_floats_at_one_point():
    """The atlas physics' one-point evaluation (bases shared by the three splines) equals :meth:`Atlas.predict`
    bit for bit, inside the grid and clipped outside it, at every amplitude."""
    import math

    from plate_env.surrogate.atlas import load_atlas_file

    for name in ("atlas_tilelink_pointmass.npz", "atlas_tilelink_rigid_limit_f2.npz"):
        atlas = load_atlas_file(name)
        rng = np.random.default_rng(5)
        for i in range(150):
            f = rng.uniform(atlas.f_hz[0] - 1.0, atlas.f_hz[-1] + 1.0)
            w = math.exp(rng.uniform(math.log(atlas.omega_n[0]) - 0.1, math.log(atlas.omega_n[-1]) + 0.1))
            a = rng.uniform(atlas.alpha[0] - 0.05, atlas.alpha[-1] + 0.05)
            amp = float(atlas.a_p_deg[i % atlas.a_p_deg.size])
            assert atlas.predict_point(f, amp, w, a) == tuple(float(v) for v in atlas.predict(f, amp, w, a))
