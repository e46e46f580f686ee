"""The atlas's alpha interpolation error measured on its own nodes (plate_env/identify/interp_error.py, issue 38
item 3)."""

from __future__ import annotations

import numpy as np
import pytest

from plate_env.identify.interp_error import HALF_GAP_SHARE, alpha_error, alpha_error_field


class _Atlas:
    """The arrays alpha_error reads, and the atlas's per-instance cache."""

    def __init__(self, mean: np.ndarray, alpha: np.ndarray):
        self.mean, self.alpha = mean, alpha
        self.f_hz = np.arange(10.0, 10.0 + mean.shape[0])
        self.a_p_deg = np.array([3.0, 12.0])[: mean.shape[1]]
        self.omega_n = np.geomspace(5.0, 50.0, mean.shape[2])
        self._cache: dict = {}

    def cached(self, key, build):
        if key not in self._cache:
            self._cache[key] = build()
        return self._cache[key]


ALPHA = np.radians([26.0, 33.6, 41.2, 48.8, 56.4, 64.0])


def test_a_cubic_response_has_no_interpolation_error():
    """A cubic spline through the other nodes reproduces a cubic in alpha exactly: no error anywhere."""
    mean = np.broadcast_to(3.0 + 40 * ALPHA - 9 * ALPHA ** 2 + 5 * ALPHA ** 3, (3, 2, 4, 6)).copy()
    assert np.max(alpha_error_field(_Atlas(mean, ALPHA))) == pytest.approx(0.0, abs=1e-9)


def test_a_peak_at_one_node_is_missed_by_the_others_spline():
    """A response zero at every alpha node but one (value 8 deg/s there): the spline through the others is zero,
    so the leave-one-out miss at that node is 8 and the error HALF_GAP_SHARE of it; its neighbours' misses are smaller
    but not zero; the end nodes take their inner neighbour's."""
    mean = np.zeros((3, 2, 4, 6))
    mean[1, 0, 2, 3] = 8.0
    err = alpha_error_field(_Atlas(mean, ALPHA))
    assert err[1, 0, 2, 3] == pytest.approx(HALF_GAP_SHARE * 8.0)
    assert 0 < err[1, 0, 2, 2] < err[1, 0, 2, 3] and err[1, 0, 2, 0] == err[1, 0, 2, 1]
    assert np.count_nonzero(err[0]) == np.count_nonzero(err[:, 1]) == 0  # other f_p, other amplitude: none
    assert not err.flags.writeable


def test_a_probes_error_reads_the_nearest_nodes_and_the_larger_of_the_two_f_nodes_around_it():
    mean = np.zeros((4, 2, 4, 6))  # f_p nodes 10, 11, 12, 13 Hz
    mean[1, 0, 2, 3] = 8.0
    atlas = _Atlas(mean, ALPHA)
    w = atlas.omega_n[[1, 2, 2]] * np.array([1.0, 1.01, 0.99])
    a = ALPHA[[3, 3]] + np.radians([0.5, -0.5])
    for f_hz in (10.5, 11.0, 11.5, 12.0):  # the f_p interval around it (at a node: the one below) holds node 11
        e = alpha_error(atlas, 3.0, f_hz, w, a)
        peak = HALF_GAP_SHARE * 8.0
        assert e.shape == (3, 2) and e[1, 0] == e[2, 1] == pytest.approx(peak) and e[0, 0] < peak, f_hz
    assert np.all(alpha_error(atlas, 3.0, 12.5, w, a) == 0)  # nodes 12-13
    assert np.all(alpha_error(atlas, 12.0, 11.0, w, a) == 0)  # the other amplitude


def test_too_few_alpha_nodes_measure_nothing():
    mean = np.zeros((2, 1, 3, 4))
    mean[..., 1] = 5.0
    assert np.all(alpha_error_field(_Atlas(mean, ALPHA[:4])) == 0)
