"""The atlas's interpolation error along alpha, measured on its own nodes (issue 38 item 3). Pure.

An atlas knows the response at its alpha nodes (the shipped tile-link ones: 6, 7.6 deg apart) and interpolates
between them with a cubic spline. Where the response peaks in alpha between two nodes the spline misses it by many
times the model error ``sigma_model`` (fitted at random held-out points, where such places are rare), and the
predictive check refused live in-model episodes whose adaptive probes sat exactly there.

Measured here, per atlas node (f_p, A_p, omega_n, alpha): leave that alpha node out, fit the same cubic spline
(scipy's ``make_interp_spline``, not-a-knot, as the atlas's) through the others along alpha, and take the absolute
miss at the node, |spline - value| (deg/s): the interpolation error over a gap of two node intervals. The error over
one interval, the atlas's own, is taken as :data:`HALF_GAP_SHARE` = 1/16 of it: a cubic spline's error shrinks as
the interval to the fourth power for a smooth response. Measured, not assumed (issue 38 item 3,
``experiments/results/check_false_refusal.md``): with 1/16 the 200 stored live bayes episodes are refused 0 times
(smallest p 0.0047) and the 60pi object of tests/test_hardening.py item 1 at p 0.00025; 1/4 (the interval squared,
for a response with a bounded second derivative only) refuses 0 too but leaves no p below 0.65 on those episodes
and costs power (rates x0.9: 31 of 100 refused against 49 with 1/16). The end nodes (no neighbour on one side)
take their inner neighbour's error.

Used by :func:`plate_env.identify.inference.predictive_check` as one more term of each probe's scale; the
likelihood (the posterior and the estimate) does not read it. Measured effect:
``experiments/results/check_false_refusal.md``.
"""

from __future__ import annotations

import numpy as np

from plate_env.surrogate.atlas import Atlas

#: The share of the leave-one-node-out error over two node intervals taken as the error over one (the interval
#: ratio to the fourth power: a cubic spline's error on a smooth response; see the module's docstring).
HALF_GAP_SHARE = 1.0 / 16.0
#: Fewest alpha nodes for the measurement: a cubic spline through the others needs 4.
MIN_ALPHA_NODES = 5


def alpha_error_field(atlas: Atlas) -> np.ndarray:
    """``HALF_GAP_SHARE`` x the leave-one-alpha-node-out error of the atlas's mean (deg/s), the mean's shape
    (f_p, A_p, omega_n, alpha); zeros for an atlas with fewer than ``MIN_ALPHA_NODES`` alpha nodes. Read-only,
    built once per atlas and kept in the disk cache (:func:`plate_env.core.cache.cached_arrays`), so that a warm
    process does not import scipy.interpolate for it."""
    from plate_env.core.cache import cached_arrays, content_key

    alpha = np.asarray(atlas.alpha, float)
    mean = np.nan_to_num(np.asarray(atlas.mean, float))

    def build() -> dict[str, np.ndarray]:
        from scipy.interpolate import make_interp_spline

        err = np.zeros(mean.shape)
        if alpha.size >= MIN_ALPHA_NODES:
            for j in range(1, alpha.size - 1):
                keep = np.arange(alpha.size) != j
                miss = make_interp_spline(alpha[keep], mean[..., keep], k=3, axis=-1)(alpha[j]) - mean[..., j]
                err[..., j] = HALF_GAP_SHARE * np.abs(miss)
            err[..., 0], err[..., -1] = err[..., 1], err[..., -2]
        return {"err": err}

    def field() -> np.ndarray:
        key = content_key("alpha-error", alpha, mean, HALF_GAP_SHARE, MIN_ALPHA_NODES)
        err = np.array(cached_arrays("alpha-error", key, build)["err"], float)
        err.flags.writeable = False
        return err

    return atlas.cached(("alpha_error_field",), field)


def alpha_error(atlas: Atlas, a_p_deg: float, f_hz: float, w: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The alpha interpolation error (deg/s) of one probe (``f_hz``, ``a_p_deg``) on the grid ``w`` (omega_n,
    rad/s) x ``a`` (alpha, rad): the larger of the two f_p nodes around ``f_hz``, at the nearest amplitude node and
    the nearest node in log omega_n and in alpha (an error of the atlas, read off its nodes, not interpolated
    further). Shape (len(w), len(a))."""
    field = alpha_error_field(atlas)
    f_nodes = np.asarray(atlas.f_hz, float)
    hi = int(np.clip(np.searchsorted(f_nodes, f_hz), 1, f_nodes.size - 1)) if f_nodes.size > 1 else 0
    lo = max(hi - 1, 0)
    amp = int(np.argmin(np.abs(np.asarray(atlas.a_p_deg, float) - abs(float(a_p_deg)))))
    per_f = np.maximum(field[lo, amp], field[hi, amp])  # (omega_n nodes, alpha nodes)
    wi = _nearest(np.log(np.asarray(atlas.omega_n, float)), np.log(np.asarray(w, float)))
    ai = _nearest(np.asarray(atlas.alpha, float), np.asarray(a, float))
    return per_f[np.ix_(wi, ai)]


def _nearest(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Index of the node nearest each ``x`` (nodes sorted ascending)."""
    if nodes.size == 1:
        return np.zeros(x.shape, int)
    mid = 0.5 * (nodes[1:] + nodes[:-1])
    return np.searchsorted(mid, x)
