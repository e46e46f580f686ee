"""The validation table's rules (experiments/validate_paper.py, experiments/falling_side.py and the helpers they share
in experiments/common.py): verdicts, the placement statistics, the observed-f0 rule and the falling-side bar, on
planted numbers. A test of the experiments' own code, beside it (pytest collects experiments/ too), so that the
package's tests in tests/ import no script."""

from __future__ import annotations

import math

import common
import falling_side as fs
import kept_12deg as k12
import numpy as np
import pytest
import validate_paper as vp

import plate_env as pe
from plate_env.identify.fitting import LorentzFit, fit_lorentzian, lorentzian
from plate_env.run.sweeps import backend_tag, load_cache, spec_key


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
    assert common.observed(good, f)
    rising = fit_lorentzian(f, lorentzian(f, 500.0, 45.0, 10.0))  # only the rising edge was probed
    assert rising.ok and rising.f0 > 30.0
    assert not common.observed(rising, f)


def test_placements_are_seeded_and_shared_between_models():
    sw = common.Sweep(10.0, 36.9, 3.0, 1)
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
    f = np.arange(20.0, 30.0)
    used = f <= 25.0
    assert common.observed(LorentzFit(ok=True, reason=None, f0=25.4, used=used), f)
    assert not common.observed(LorentzFit(ok=True, reason=None, f0=25.6, used=used), f)
    assert not common.observed(LorentzFit(ok=False, reason="x", f0=22.0, used=used), f)


def test_falling_side_peak_is_the_hump_not_the_climb_above_the_window():
    f = np.arange(18.0, 40.01, 2.0)
    w = np.where(f <= 32.0, lorentzian(f, 500.0, 25.0, 15.0), 800.0)  # a gentle fall, then the high climb
    m = fs.bar_metric(f, w, np.ones(f.size, bool), 25.1, 5.1)
    assert m["peak"] == pytest.approx(w[f <= 32.75].max())
    assert m["ratio"] > 0.6  # against the climb's 800 it would read 0.51


def _planted_rows(monkeypatch, tmp_path, fitted: dict[tuple[float, float], float], drop_placement: int | None = None):
    """model_rows("rigid_limit") on planted sweeps: every sweep of the plan complete and stable, and a first-hump fit
    (f0 from ``fitted[(omega_pi, alpha_deg)]`` at 12 deg, 25 Hz + omega_pi / 10 at 3 deg) only where planted."""
    from types import SimpleNamespace

    def fit_of(sw):
        if sw.a_p_deg == 3.0:
            return LorentzFit(ok=True, reason=None, omega_max=500.0 + sw.omega_pi, f0=25.0 + sw.omega_pi / 10, b=5.0)
        f0 = fitted.get((sw.omega_pi, sw.alpha_deg))
        if f0 is None:
            return LorentzFit(ok=False, reason="planted: no hump")
        return LorentzFit(ok=True, reason=None, omega_max=300.0 + sw.alpha_deg, f0=f0, b=2.0)

    got = {}
    for sw in common.plan("rigid_limit"):
        for p in range(common.PLACEMENTS["rigid_limit"]):
            if p == drop_placement and sw.stage == 3:  # a simulation cut off before this placement's stage 3
                continue
            got[(sw, p)] = [SimpleNamespace(spec=SimpleNamespace(motion=SimpleNamespace(freq_hz=f)), unstable=False,
                                            omega_b_deg_s=300.0, stderr_deg_s=1.0, reason=None, planted=fit_of(sw))
                            for f in common.freqs("rigid_limit", sw.a_p_deg)]
    monkeypatch.setattr(vp, "cached_sweeps", lambda model, cache_dir: got)
    monkeypatch.setattr(vp, "fit_sweep", lambda results: results[0].planted)
    return vp.model_rows("rigid_limit", tmp_path)["rows"]


def test_eq10_rows_from_fits_at_one_omega_n_say_no_estimate(monkeypatch, tmp_path):
    """The defect of issue 27: rigid_limit at 12 deg fits only the 10pi object (at 3 of 4 friction angles), and the
    line omega_n ~ f0 through one omega_n came out as p1 0.00 +- 0.00, q1 10.0, R^2 0.00, each "disagrees". Such a row
    has no estimate and says how many fits it had; so does Fig. 10's 12 deg range."""
    rows = _planted_rows(monkeypatch, tmp_path, {(10.0, 30.0): 14.0, (10.0, 36.9): 13.8, (10.0, 45.0): 12.7})
    for k in ("p1", "q1", "r2_f0", "r2_max"):
        st = rows[f"eq10_12deg_{k}"]
        assert vp.verdict(st, 5.65) == "no estimate", (k, st["value"], st.get("u"))
        assert st["objects_fitted"] == [3, 3] and st["omega_levels"] == [1, 1]
        cell = vp._cell({**st, "verdict": vp.verdict(st, 5.65)}, 2)
        assert cell.startswith("no estimate (fits of 16 per placement: 3, 3, at 1, 1 omega_n"), cell
    assert vp.range_verdict(rows, 12.0, 2)["verdict"] == "no estimate"
    # at 3 deg every object fitted, on a planted line omega_n = 10 (f0 - 25): the regression is exact
    assert rows["eq10_3deg_p1"]["value"] == pytest.approx(10.0)
    assert rows["eq10_3deg_q1"]["value"] == pytest.approx(-250.0)
    assert rows["eq10_3deg_r2_f0"]["value"] == pytest.approx(1.0)


def test_eq10_needs_fits_at_three_omega_n():
    two = [(6.5, 13.0, 300.0), (6.5, 13.2, 310.0), (10.0, 14.2, 336.0)]  # the point mass's 4th placement at 12 deg
    r = vp.eq10_regression(two, 16)
    assert "p1" not in r and r["n_fit"] == 3 and r["n_levels"] == 2
    assert r["why"].startswith("3 fits of 16 at 2 omega_n")
    three = [*two, (3.5, 12.0, 280.0)]
    r = vp.eq10_regression(three, 16)
    assert r["n_levels"] == 3 and math.isfinite(r["p1"]) and r["p1"] > 0
    assert (r["f0_min"], r["f0_max"]) == (12.0, 14.2)


def test_a_no_estimate_cell_never_shows_a_bare_number():
    st = vp._stats([None, None, None, 335.8])  # one placement of four gave a value
    cell = vp._cell({**st, "verdict": vp.verdict(st, 382.4)}, 1)
    assert cell.startswith("no estimate (1/4 placements gave a value") and "335.8" not in cell


@pytest.mark.parametrize(("model", "reason"), [("rigid", "folded"), ("pointmass", "slipped")])
def test_a_soft_disc_at_12_deg_is_reported_as_folded_or_slipped(model, reason):
    """Item 3 of issue 27 (a detected, reported failure): the table's 12 Hz probe of the 1.4pi disc at 12 deg
    (first placement) folds in the rigid-tile model and slips in the point mass, within ~0.5 s of a 1.7 s probe. The
    probe says so (unstable, with that reason, ended early) instead of returning a silent omega_B, and the table's
    Fig. 3 cell does not use it."""
    spec = next(s for s in common.Sweep(1.4, 36.9, 12.0, 2).specs(model, 0) if s.motion.freq_hz == 12.0)
    res = pe.make_physics("tilelink", model=model).run([spec])[0]
    assert res.unstable and res.reason == reason, (res.unstable, res.reason, res.omega_b_deg_s)
    assert res.sim_s < spec.motion.ramp_s + spec.settle_s + spec.measure_s
    assert vp._stats([None if res.unstable else abs(res.omega_b_deg_s)])["value"] is None


def test_a_cut_off_row_is_not_run_while_its_missing_placements_could_change_it(monkeypatch, tmp_path):
    """PyBullet's stage 3 may be cut off after its first placement: a row that one more placement could still turn
    into an estimate is "not run (1/2 placements run)"; one that has no estimate whatever it gives keeps that."""
    rows = _planted_rows(monkeypatch, tmp_path, {(10.0, 30.0): 14.0}, drop_placement=1)
    three = rows["eq10_3deg_p1"]  # placement 0 gives p1 = 10 exactly; placement 1 missing
    assert three["placements_run"] == 1 and three["n"] == 1
    assert vp.row_verdict(three, 5.3, 2) == "not run"
    assert vp._cell({**three, "verdict": "not run", "of_planned": 2}, 2) == "not run (1/2 placements run)"
    twelve = rows["eq10_12deg_p1"]  # placement 0 has no estimate: one more placement cannot give two values
    assert twelve["placements_run"] == 1 and twelve["n"] == 0
    assert vp.row_verdict(twelve, 5.65, 2) == "no estimate"
    assert vp.row_verdict(twelve, 5.65, 3) == "not run"  # with 3 planned, two more could still give two values
    assert vp.range_verdict(rows, 3.0, 2) == {"paper": [23.0, 30.0], "verdict": "not run",
                                              "why": "1/2 placements run"}
    assert vp.range_verdict(rows, 12.0, 2)["verdict"] == "no estimate"
    full = vp._stats([10.0, 12.0, 14.0])
    assert vp.row_verdict(full, 12.0, 3) == vp.verdict(full, 12.0) == "agrees"


def test_kept_12deg_keeps_only_slipped_probes_that_measured_a_period():
    from plate_env.core.probe import ProbeResult

    spec = common.Sweep(10.0, 36.9, 12.0, 2).specs("rigid", 0)[0]
    mk = lambda un, why, n: ProbeResult(spec=spec, omega_b_deg_s=300.0, stderr_deg_s=1.0, unstable=un,  # noqa: E731
                                        reason=why, sim_s=1.0, wall_s=0.1, periods_measured=n)
    out = common.kept([mk(True, "slipped", 3), mk(True, "slipped", 0), mk(True, "folded", 5), mk(False, None, 12)])
    assert [r.unstable for r in out] == [False, True, True, False]


def test_kept_12deg_bar_needs_every_soft_object_in_range_and_a_rising_f0():
    paper = {w: (w + 64.51) / 5.65 for w in (1.4, 3.5, 6.5, 10.0)}  # Eq. (10) at 12 deg: 11.7-13.2 Hz
    assert k12.bar(paper)["meets_bar"]
    assert not k12.bar({**paper, 1.4: None})["meets_bar"]  # one object lost
    assert not k12.bar({**paper, 10.0: 14.2})["meets_bar"]  # above 14 Hz
    assert not k12.bar({w: 14.0 - 0.1 * w for w in paper})["meets_bar"]  # falling with omega_n
    assert k12.median_f0([LorentzFit(ok=True, reason=None, f0=12.0), LorentzFit(ok=False, reason="x")]) == 12.0
    assert k12.median_f0([LorentzFit(ok=True, reason=None, f0=12.0)] + [LorentzFit(ok=False, reason="x")] * 2) is None


def test_pybullet_hump_finer_sweep_copies_the_tables_probes_and_refuses_off_grid(tmp_path):
    import json

    import pybullet_hump as ph

    assert ph.parse_freqs("12:16:1") == (12.0, 13.0, 14.0, 15.0, 16.0)
    with pytest.raises(ValueError, match="LO:HI:STEP"):
        ph.parse_freqs("12-24")
    with pytest.raises(ValueError, match="not on the 3 deg grid"):
        common.Sweep(10.0, 36.9, 3.0, 1).specs("pybullet", 0, (12.5,))
    physics, _ = ph.variant("static")
    fine = common.Sweep(10.0, 36.9, 3.0, 1).specs("pybullet", 0, (12.0, 13.0, 14.0))
    table = common.Sweep(10.0, 36.9, 3.0, 1).specs("pybullet", 0)
    assert fine[0] == table[0] and fine[2] == table[1]  # the shared frequencies are the table's own probes
    tag = backend_tag(physics)
    source, cache = tmp_path / "table.jsonl", tmp_path / "hump.jsonl"
    source.write_text("".join(json.dumps({"key": spec_key(tag, s), "omega_b_deg_s": 1.0, "stderr_deg_s": 0.1,
                                          "unstable": False, "reason": None, "sim_s": 1.0, "wall_s": 1.0,
                                          "periods_measured": 5}) + "\n" for s in table[:2]))
    before = source.read_text()
    assert ph.copy_records(physics, fine, source, cache) == 2
    assert ph.copy_records(physics, fine, source, cache) == 0  # already there
    assert source.read_text() == before
    assert set(load_cache(cache)) == {spec_key(tag, fine[0]), spec_key(tag, fine[2])}
