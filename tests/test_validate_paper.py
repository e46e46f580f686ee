"""The validation table's rules (experiments/validate_paper.py, experiments/falling_side.py): verdicts, the
placement statistics, the observed-f0 rule and the falling-side bar, on planted numbers."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
import falling_side as fs  # noqa: E402
import validate_paper as vp  # noqa: E402

from plate_env.identify.fitting import fit_lorentzian, lorentzian  # noqa: E402


def test_stats_median_spread_and_uncertainty():
    st = vp._stats([10.0, 12.0, None, 14.0], [1.0, 1.0, None, 1.0])
    assert st["n"] == 3 and st["of"] == 4
    assert st["value"] == 12.0
    assert st["sd"] == pytest.approx(2.0)
    assert st["u"] == pytest.approx(math.sqrt(4.0 + 1.0))


def test_verdict_follows_the_stated_rule():
    assert vp.K == pytest.approx(2.0 * math.sqrt(2.0))  # the rule the table states
    st = vp._stats([10.0, 12.0, 14.0], [0.0, 0.0, 0.0])  # u = 2
    edge = 12.0 + vp.K * 2.0
    assert vp.verdict(st, edge - 1e-6) == "agrees"
    assert vp.verdict(st, edge + 1e-6) == "disagrees"
    assert vp.verdict(vp._stats([10.0, None]), 10.0) == "no estimate"


def test_a_fit_whose_top_lies_outside_its_probes_is_not_used():
    f = np.arange(10.0, 30.0)
    good = fit_lorentzian(f, lorentzian(f, 500.0, 22.0, 4.0))
    assert vp.observed(good, f)
    rising = fit_lorentzian(f, lorentzian(f, 500.0, 45.0, 10.0))  # only the rising edge was probed
    assert rising.ok and rising.f0 > 30.0
    assert not vp.observed(rising, f)


def test_placements_are_seeded_and_shared_between_models():
    sw = vp.Sweep(10.0, 36.9, 3.0, 1)
    a, b = sw.specs("rigid", 1), sw.specs("rigid", 1)
    assert [s.initial_offset for s in a] == [s.initial_offset for s in b]
    assert [s.initial_offset for s in a] != [s.initial_offset for s in sw.specs("rigid", 0)]
    assert [s.initial_yaw for s in a] == [s.initial_yaw for s in sw.specs("pointmass", 1)]


def test_falling_side_bar_on_planted_curves():
    f = np.arange(18.0, 38.01, 2.0)
    falls = lorentzian(f, 600.0, 25.1, 5.1)
    m = fs.bar_metric(f, falls, np.ones(f.size, bool), 25.1, 5.1)
    assert m["meets_bar"] and m["ratio"] == pytest.approx(falls[f == 32.0][0] / falls.max())
    rises = np.linspace(300.0, 800.0, f.size)
    assert not fs.bar_metric(f, rises, np.ones(f.size, bool), 25.1, 5.1)["meets_bar"]
    # the fall only among unstable probes does not count
    ok = f <= 26.0
    assert fs.bar_metric(f, falls, ok, 25.1, 5.1)["ratio"] > 0.6


def test_observed_allows_half_a_probe_spacing_beyond_the_fitted_probes():
    from plate_env.identify.fitting import LorentzFit

    f = np.arange(20.0, 30.0)
    used = f <= 25.0
    assert vp.observed(LorentzFit(ok=True, reason=None, f0=25.4, used=used), f)
    assert not vp.observed(LorentzFit(ok=True, reason=None, f0=25.6, used=used), f)
    assert not vp.observed(LorentzFit(ok=False, reason="x", f0=22.0, used=used), f)


def test_falling_side_peak_is_the_hump_not_the_climb_above_the_window():
    f = np.arange(18.0, 40.01, 2.0)
    w = np.where(f <= 32.0, lorentzian(f, 500.0, 25.0, 15.0), 800.0)  # a gentle fall, then the high climb
    m = fs.bar_metric(f, w, np.ones(f.size, bool), 25.1, 5.1)
    assert m["peak"] == pytest.approx(w[f <= 32.75].max())
    assert m["ratio"] > 0.6  # against the climb's 800 it would read 0.51
