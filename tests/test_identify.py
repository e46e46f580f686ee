"""The identification API (plate_env.identify): both methods, several amplitudes, refusals as results."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify
from plate_env.identify.calibration import (
    paper_calibration,
)
from plate_env.identify.fitting import lorentzian
from plate_env.identify.lorentz import identify_lorentz
from plate_env.surrogate.atlas import load_atlas


def test_identify_lorentz_combines_amplitudes_by_inverse_variance():
    """The Eq. (9)/(10) arithmetic (identify_lorentz): made-up Lorentzians, which the tile-link model's check gating
    ``identify(method="lorentz")`` rightly refuses (tests/test_hardening3_contract.py), so they are read ungated."""
    f = np.arange(10.0, 40.01, 2.0)
    cals = {3.0: paper_calibration(3), 12.0: paper_calibration(12)}
    t3 = ProbeTable.from_arrays(f, 3.0, lorentzian(f, 600, 25.1, 5.1), np.full(f.size, 5.0))
    t12 = ProbeTable.from_arrays(f, 12.0, lorentzian(f, 380, 13.0, 3.0), np.full(f.size, 5.0))
    both = ProbeTable(*(np.concatenate([getattr(t3, k), getattr(t12, k)]) for k in
                        ("f_p_hz", "a_p_deg", "omega_b_deg_s", "stderr_deg_s", "unstable")))
    e3 = identify_lorentz(t3, calibrations=cals)
    e12 = identify_lorentz(t12, calibrations=cals)
    eb = identify_lorentz(both, calibrations=cals)
    assert e3.ok and e12.ok and eb.ok
    w3, w12 = 1 / e3.omega_n_stderr ** 2, 1 / e12.omega_n_stderr ** 2
    assert eb.omega_n == pytest.approx((w3 * e3.omega_n + w12 * e12.omega_n) / (w3 + w12))
    assert eb.omega_n_stderr < min(e3.omega_n_stderr, e12.omega_n_stderr)


def test_identify_reports_cannot_fit():
    est = identify(ProbeTable.from_arrays([20.0, 25.0], 3.0, [100.0, 200.0]), method="lorentz", physics="paper")
    assert not est.ok and "at least 4" in est.reason
    with pytest.raises(ValueError, match="unknown identification method"):
        identify(ProbeTable.from_arrays([20.0], 3.0, [1.0]), method="magic")


def test_shipped_atlas_loads_and_identifies_one_sided_mixed_data():
    atlas = load_atlas("tilelink", "pointmass")
    w_true, a_true = 17 * math.pi, math.radians(45)
    f = np.array([12.0, 16.0, 19.0, 21.0])  # rising side only
    mu3, _, _ = atlas.predict(f, 3.0, w_true, a_true)
    mu12, _, _ = atlas.predict(f[:2], 12.0, w_true, a_true)
    table = ProbeTable.from_arrays(np.r_[f, f[:2]], np.r_[[3.0] * 4, [12.0] * 2], np.r_[mu3, mu12])
    est = identify(table, method="atlas")
    assert est.ok and est.omega_n_ci95[0] <= w_true <= est.omega_n_ci95[1]


def test_lorentz_intervals_of_a_positive_quantity_are_cut_at_zero_not_the_estimate():
    """omega_n > 0: a normal interval reaching below 0 ends at 0 (the estimate and its stderr are untouched)."""
    from plate_env.identify import positive_intervals

    assert positive_intervals(30.0, 5.0) == ((25.0, 35.0), (pytest.approx(20.2), pytest.approx(39.8)))
    ci68, ci95 = positive_intervals(34.4, 22.9)
    assert ci68 == (pytest.approx(11.5), pytest.approx(57.3)) and ci95[0] == 0.0
    assert ci95[1] == pytest.approx(34.4 + 1.96 * 22.9)
