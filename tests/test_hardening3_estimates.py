"""Issue 37 (hardening round three): every estimator refuses what it cannot explain. Each test fails before its fix."""

from __future__ import annotations

import numpy as np
import pytest

from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify, identify_lorentz

F_HZ = np.arange(10.0, 41.0, 2.0)
#: A point-mass-like rise cut by instability at 22 Hz and from 30 Hz on (the shape of `plate-env identify --agent grid
#: --physics tilelink --omega-n 50pi`), its last stable value raised so that the Lorentzian's top lands past 28 Hz.
RISE = [12.1, 69.6, 83.8, 102.2, 140.1, 275.5, 0.0, 494.3, 584.8, 660.0] + [0.0] * 6


def _table(values) -> ProbeTable:
    values = np.asarray(values, dtype=float)
    return ProbeTable.from_arrays(F_HZ, np.full(F_HZ.size, 3.0), values, np.full(F_HZ.size, 2.0), values == 0.0)


def test_item2_a_lorentz_peak_beyond_the_probes_it_was_fitted_on_is_no_estimate():
    est = identify(_table(RISE), method="lorentz", physics="tilelink", model="pointmass")
    assert not est.ok and not est.omega_n
    assert "lies above the probes the fit used (20-28 Hz)" in est.reason and "f0 = 28.4 Hz" in est.reason
    assert est.fits[3.0].ok and est.fits[3.0].f0 > 28.0  # the fit itself succeeded: the read of it is refused


def test_item2_a_measured_lorentz_peak_is_still_read():
    from plate_env.identify.fitting import lorentzian

    values = np.where(F_HZ > 34, 0.0, lorentzian(F_HZ, 600.0, 31.0, 6.0))
    # the method's own read (identify_lorentz): a made-up Lorentzian is no point-mass sweep, and the estimate
    # contract refuses it by the model's check (test_hardening3_contract.py)
    est = identify_lorentz(_table(values), physics="tilelink", model="pointmass")
    assert est.ok and est.omega_n_ci95[0] <= est.omega_n <= est.omega_n_ci95[1]


@pytest.mark.parametrize("last", [640.0, 660.0])
def test_item2_the_rule_reads_the_fit_window_not_the_sweep(last):
    """The same sweep with its last stable value 640 deg/s peaks inside the window (27.9 Hz) and is read."""
    est = identify_lorentz(_table(RISE[:9] + [last] + RISE[10:]), physics="tilelink", model="pointmass")
    assert est.ok == (last == 640.0)
