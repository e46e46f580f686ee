"""Hardening, round two (issue 28): each numbered item of the issue has a test here that failed before its fix,
named ``test_itemN_...``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify
from plate_env.identify.estimate import Estimate, Posterior
from plate_env.identify.forward import load_forward_model

#: The probes the bayes agent took on `identify --agent bayes --physics tilelink --omega-n 60pi --alpha 45 --seed 0`
#: (f_p Hz, A_p deg, omega_B deg/s, stderr deg/s, unstable): main 284a76f answered 18.06pi, 95 % [17.1, 19.3]pi.
ABOVE_RANGE_60PI = [(25.0, 3.0, 534.22, 0.34, 0), (14.5, 3.0, 87.93, 0.339, 0), (14.0, 3.0, 82.93, 0.312, 0),
                    (26.5, 3.0, 588.18, 0.485, 0), (16.0, 3.0, 105.37, 0.313, 0), (25.5, 3.0, 551.0, 0.392, 0),
                    (28.0, 3.0, 632.31, 0.455, 0), (15.5, 12.0, 0.0, 0.0, 1), (26.0, 3.0, 570.49, 0.424, 0),
                    (28.5, 3.0, 0.0, 0.0, 1), (23.0, 3.0, 468.58, 0.412, 0), (29.0, 3.0, 660.24, 1.244, 0)]
#: `plate-env sweep --physics tilelink --model pointmass --omega-n 10pi --alpha 80` (10-40 Hz, 1 Hz) at 3 deg.
ALPHA_80_3DEG = [(10.0, 0.0, 0.0, 0), (11.0, 0.0, 0.0, 0), (12.0, 0.01, 0.001, 0), (13.0, 0.01, 0.002, 0),
                 (14.0, 0.02, 0.001, 0), (15.0, 1.76, 0.003, 0), (16.0, 6.89, 0.154, 0), (17.0, 11.15, 0.324, 0),
                 (18.0, 56.47, 7.144, 0), (19.0, 162.24, 1.303, 0), (20.0, 207.09, 2.144, 0), (21.0, 235.6, 3.679, 1),
                 (22.0, 263.78, 4.352, 1), (23.0, 305.98, 10.548, 1), (24.0, 326.71, 4.492, 1),
                 (25.0, 350.86, 4.055, 1)] + [(float(f), 0.0, 0.0, 1) for f in range(26, 41)]


def _table(rows) -> ProbeTable:
    f, a, w, se, un = zip(*rows, strict=True)
    return ProbeTable.from_arrays(f, a, w, se, np.array(un, bool))


def _honest_sweep(omega_n: float, alpha_deg: float, a_p_deg: float, seed: int) -> ProbeTable:
    """A sweep drawn from the shipped point-mass forward model itself: its atlas's mean at the object, residuals
    Student-t (nu 4) of its own scale, instability flags from its own probabilities."""
    from plate_env.identify.inference import NU, smoothed_p

    m = load_forward_model("tilelink/pointmass").members[0]
    rng = np.random.default_rng(seed)
    f = np.arange(10.0, 40.5, 1.0)
    mu, s, p = m.atlas.predict(f, a_p_deg, omega_n, math.radians(alpha_deg))
    se = np.full(f.size, 0.5)
    un = rng.random(f.size) < smoothed_p(np.clip(p, 0, 1), m.atlas.n_repeats)
    y = mu + rng.standard_t(NU, f.size) * np.sqrt(s ** 2 + se ** 2 + m.sigma_model ** 2)
    return ProbeTable.from_arrays(f, a_p_deg, np.where(un, 0.0, y), np.where(un, 0.0, se), un)


# ------------------------------------------------------------------------------------------- 1-3: wrong answers
def test_item1_an_object_above_the_identifiable_range_gets_no_confident_number():
    """The bayes agent's own estimate model (its blur and design discrepancy) on its probes of a 60pi object."""
    from plate_env_agents.bayes import BayesAgent

    agent = BayesAgent()
    agent.fm = load_forward_model("tilelink/pointmass")
    est = identify(_table(ABOVE_RANGE_60PI), forward=agent.estimate_model())
    assert not est.ok, f"a confident {est.omega_n / math.pi:.2f}pi for an object at 60pi"
    assert est.check is not None and not est.check.passed
    # the reason names the forward model that read the probes and the member checked (issue 36)
    assert f"not a sweep the forward model {agent.estimate_model().name!r} can explain" in est.reason
    assert "its best-fitting member 'tilelink/pointmass'" in est.reason and "p-value" in est.reason


def test_item1_why_no_bound_the_estimate_models_posterior_is_not_at_the_edge():
    """The evidence for docs/hardening.md's decision (no bound for the 60pi object): the posterior of the model the
    agent estimates with holds almost nothing near the top of the identifiable range (45pi) -- it sits at ~18pi, so
    a bound "omega_n > 45pi" is not what that posterior says -- while the plain model piles there and fails the
    check too. Either way the data are ones no atlas object makes (p < 1e-3)."""
    from plate_env.identify.inference import posterior, predictive_check
    from plate_env_agents.bayes import BayesAgent

    agent = BayesAgent()
    agent.fm = load_forward_model("tilelink/pointmass")
    table = _table(ABOVE_RANGE_60PI)
    for fm, top_mass in ((agent.estimate_model(), (0.0, 1e-3)), (agent.fm, (0.5, 1.0))):
        post = posterior(fm, table)
        marg = post.marginal_omega() / post.marginal_omega().sum()
        near_top = float(marg[post.omega_n > 40 * math.pi].sum())
        assert top_mass[0] <= near_top <= top_mass[1], (fm.name, near_top)
        assert not predictive_check(fm, table, post).passed
        assert not identify(table, forward=fm).ok


def test_item2_a_friction_angle_outside_the_atlas_is_flagged():
    rows = [(f, 3.0, w, se, u) for f, w, se, u in ALPHA_80_3DEG]
    est = identify(_table(rows), forward="tilelink/pointmass")  # main: 1.5pi +- 0.25 for a 10pi object
    assert not est.ok and est.reason
    # the edge rule itself: a posterior piled at an end of the alpha range is flagged, an undetermined one is not
    w, a = np.geomspace(10, 100, 5), np.linspace(0.5, 1.1, 31)
    piled = np.zeros((5, 31))
    piled[2, -1] = 0.9
    piled[2, :] = piled[2] + 0.1 / 31
    assert Posterior(w, a, piled / piled.sum()).alpha_edge() == "above"
    assert Posterior(w, a, piled[:, ::-1] / piled.sum()).alpha_edge() == "below"
    flat = np.ones((5, 31)) / (5 * 31)
    assert Posterior(w, a, flat).alpha_edge() is None


@pytest.mark.parametrize("seed", range(6))
def test_item2_all_zero_rotation_at_12_deg_is_no_estimate_and_a_bound_only_where_every_alpha_says_so(seed):
    """At 12 deg most probes end unstable; the few stable ones all at 0 deg/s pile alpha at its top edge: never an
    estimate, and an omega_n bound exactly when the models put omega_n beyond their range at the friction angles
    inside the range too (the pile is the data's, not bought by the alpha edge). Which of the two a sweep gets
    depends on its unstable pattern (and, near the edge mass, on the CPU and library versions: a fresh machine with
    AVX-512 and numpy 2.4 / scipy 1.17 gave no bound for the seed an earlier machine bounded), so the rule is
    checked on six sweeps rather than one outcome pinned; the rule's two cases are pinned on a made-up posterior in
    the next test."""
    t = _honest_sweep(10 * math.pi, 45.0, 12.0, seed=seed)
    zero = ProbeTable(t.f_p_hz, t.a_p_deg, 0 * t.omega_b_deg_s, t.stderr_deg_s, t.unstable)
    est = identify(zero, forward="tilelink/pointmass")
    post = est.posterior
    assert not est.ok and post.alpha_edge() == "above", est.reason
    every_alpha = post.edge() if post.edge() == post.edge_at_inner_alpha() else None
    assert (est.bound[0] if est.bound is not None else None) == every_alpha, (est.bound, post.edge(),
                                                                                post.edge_at_inner_alpha())


def test_item2_an_omega_pile_bought_by_the_alpha_edge_gives_no_bound():
    """The rule itself: omega_n piled at its top only in the two alpha columns at an end (the data explained by
    a friction angle the models do not reach) is no bound; piled at every alpha, it is."""
    from plate_env.identify.inference import atlas_estimate

    w, a = np.geomspace(10, 100, 9), np.linspace(0.5, 1.1, 31)
    only_edge = np.full((9, 31), 1e-3)
    only_edge[4, :] = 0.2  # inside the range the data put omega_n mid-range
    only_edge[-1, -2:] = 1.0
    every = np.full((9, 31), 1e-3)
    every[-1, :] = 0.2
    every[-1, -2:] = 1.0
    for prob, inner in ((only_edge, None), (every, "above")):
        post = Posterior(w, a, prob / prob.sum(), identifiable_range=(10.0, 100.0))
        assert post.alpha_edge() == "above" and post.edge() == "above" and post.edge_at_inner_alpha() == inner
    fm = load_forward_model("tilelink/pointmass")
    t = _honest_sweep(10 * math.pi, 45.0, 3.0, seed=1)

    def estimate(prob):
        post = Posterior(w, a, prob / prob.sum(), identifiable_range=(10.0, 100.0))
        return atlas_estimate(fm, t, [], lambda: post, response=lambda *args, **kw: None)

    from unittest import mock

    from plate_env.identify import inference
    from plate_env.identify.estimate import PredictiveCheck

    passed = PredictiveCheck(statistic=0.0, p_value=0.5, n_probes=len(t), member="m", worst=None)
    with mock.patch.object(inference, "predictive_check", lambda *args, **kw: passed):
        no_bound, bound = estimate(only_edge), estimate(every)
    assert not no_bound.ok and no_bound.bound is None and "only with alpha at its edge" in no_bound.reason
    assert not bound.ok and bound.bound is not None and bound.bound[0] == "above"


@pytest.mark.parametrize("bad", ["zero", "negative", "x100"])
def test_item3_data_no_object_could_make_is_no_estimate_with_the_check_in_json(bad):
    t = _honest_sweep(8.5 * math.pi, 45.0, 3.0, seed=1)
    y = {"zero": 0 * t.omega_b_deg_s, "negative": -np.abs(t.omega_b_deg_s), "x100": 100 * t.omega_b_deg_s}[bad]
    est = identify(ProbeTable(t.f_p_hz, t.a_p_deg, y, t.stderr_deg_s, t.unstable), forward="tilelink/pointmass")
    assert not est.ok and "can explain" in est.reason
    d = json.loads(json.dumps(est.to_dict(), allow_nan=False))
    assert d["check"]["passed"] is False and d["check"]["p_value"] < d["check"]["p_min"]
    assert Estimate.from_dict(d).check == est.check


def test_item3_honest_sweeps_from_the_model_pass_the_check():
    """Sweeps drawn from the model itself pass (the measured false-rejection rate on the live within-model test
    set is in experiments/results/predictive_check.md); a pass carries its p-value in the JSON."""
    p = []
    for seed, (w_pi, alpha, amp) in enumerate([(4.0, 35.0, 3.0), (8.5, 45.0, 3.0), (20.0, 55.0, 3.0),
                                               (12.0, 40.0, 12.0)]):
        est = identify(_honest_sweep(w_pi * math.pi, alpha, amp, seed), forward="tilelink/pointmass")
        assert est.check is not None and est.check.passed, (w_pi, est.check)
        p.append(est.check.p_value)
        assert est.to_dict()["check"]["p_value"] == est.check.p_value
    assert min(p) > 0.001


def test_item3_the_check_is_deterministic_and_its_p_value_calibrated_on_its_own_replicates():
    from plate_env.identify.estimate import PredictiveCheck
    from plate_env.identify.inference import predictive_check

    t = _honest_sweep(8.5 * math.pi, 45.0, 3.0, seed=1)
    fm = load_forward_model("tilelink/pointmass")
    a = identify(t, forward=fm)
    b = predictive_check(fm, t, a.posterior)
    assert isinstance(b, PredictiveCheck) and b == a.check  # a pure function: the same probes, the same check
    assert 0.0 < b.p_value <= 1.0 and b.n_probes == len(t)


# ------------------------------------------------------------------------------------------- 4-6
@pytest.mark.parametrize("name, options", [("tilelink", {"slip_limit": 0.005}),
                                           ("pybullet", {"k_elastic": 50.0}),
                                           ("pybullet", {"stderr_tol_deg_s": 0.5}),
                                           ("atlas", {"instability_rho": 0.9}),
                                           ("atlas", {"instability_rho": 0.9, "instability_corr_hz": 5.0})])
def test_item4_every_option_that_changes_results_is_in_the_sweep_cache_key(name, options):
    from plate_env.run.executor import BackendSpec
    from plate_env.run.sweeps import backend_tag

    base = {"atlas": {"instability_rho": 0.9}}.get(name, {}) if "instability_corr_hz" in options else {}
    assert backend_tag(BackendSpec.of(name, **options)) != backend_tag(BackendSpec.of(name, **base))


def test_item4_caches_of_the_default_settings_keep_their_keys():
    from plate_env.run.executor import BackendSpec
    from plate_env.run.sweeps import backend_tag

    for name in ("tilelink", "pybullet", "atlas"):
        tag = backend_tag(BackendSpec.of(name))
        assert not any(f",{k}=" in tag for k in ("slip_limit", "k_elastic", "stderr_tol_deg_s", "rho", "corr_hz")), tag


def test_item6_member_weights_of_members_sharing_a_label_are_summed():
    w, a = np.geomspace(10, 100, 5), np.linspace(0.5, 1.1, 7)
    post = Posterior(w, a, np.ones((5, 7)) / 35, members=("tilelink/pointmass",) * 3 + ("pybullet/pybullet",),
                     member_weights=(0.3, 0.2, 1e-15, 0.5))
    est = Estimate(ok=True, method="atlas", omega_n=30.0, omega_n_ci68=(25.0, 35.0), omega_n_ci95=(20.0, 40.0),
                   posterior=post)
    members = est.to_dict()["members"]
    assert members == pytest.approx({"tilelink/pointmass": 0.5, "pybullet/pybullet": 0.5})
    assert sum(members.values()) == pytest.approx(1.0)


@pytest.mark.parametrize("kind", ["make_vec", "sb3"])
def test_item5_a_vector_step_refused_for_one_sub_env_draws_nothing(kind):
    """Sub-env 1's NaN action is refused before sub-env 0 draws its probe's placement: the next step equals that
    of a clean run."""
    import gymnasium as gym

    kwargs = dict(physics="atlas", max_probes=5)

    def make():
        if kind == "make_vec":
            return gym.make_vec("PlateRotation-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
        from plate_env.env.sb3 import PlateRotationSB3VecEnv

        return PlateRotationSB3VecEnv(2, **kwargs)

    good = np.array([[0.1, -0.5, 0.0, -1.0], [0.3, -0.5, 0.0, -1.0]], dtype=np.float32)
    bad = good.copy()
    bad[1, 0] = np.nan
    outs = []
    for refuse_first in (False, True):
        env = make()
        if kind == "make_vec":
            env.reset(seed=4)
        else:
            env.seed(4)
            env.reset()
        if refuse_first:
            with pytest.raises(ValueError, match="NaN"):
                env.step(bad)
        out = env.step(good)
        outs.append(out[0])
        env.close()
    assert np.array_equal(outs[0], outs[1])


# ------------------------------------------------------------------------------------------- 7-12: lost or hung work
def _atlas_specs(freqs=(15.0, 20.0, 25.0)):
    import plate_env

    obj = plate_env.ObjectSpec.from_paper(10.0, 36.9)
    return [plate_env.ProbeSpec(obj, plate_env.PlateMotion.from_paper(f, 3.0)) for f in freqs]


def test_item7_a_full_disk_during_a_sweep_keeps_the_probes_and_names_the_cache(tmp_path, monkeypatch):
    from plate_env.run import sweeps
    from plate_env.run.executor import BackendSpec

    class Full:
        def write(self, data):
            raise OSError(28, "No space left on device")

        def flush(self):
            pass

        def close(self):
            pass

    monkeypatch.setattr(sweeps, "open_for_append", lambda path: Full())
    cache = tmp_path / "sweep.jsonl"
    with pytest.warns(UserWarning, match=r"cannot write the cache .*sweep\.jsonl.*No space left"):
        res = sweeps.run_cached(BackendSpec.of("atlas"), _atlas_specs(), cache, chunk=1, progress=False)
    assert len(res) == 3 and all(math.isfinite(r.omega_b_deg_s) for r in res)


@pytest.mark.parametrize("command", ["sweep", "bench"])
@pytest.mark.parametrize("kind", ["device", "fifo", "directory"])
def test_item8_a_cache_that_is_not_a_regular_file_is_refused_before_work(tmp_path, capsys, command, kind):
    import os

    from plate_env.cli import main

    path = {"device": "/dev/zero", "fifo": str(tmp_path / "fifo"), "directory": str(tmp_path)}[kind]
    if kind == "fifo":
        os.mkfifo(path)
    argv = (["sweep", "--physics", "atlas", "--freqs", "20", "--no-progress", "--cache", path] if command == "sweep"
            else ["bench", "--suite", "atlas-v0", "--agent", "grid", "--limit", "1", "--no-progress", "--cache", path])
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "not a regular file" in err and path in err and err.count("\n") == 1


@pytest.mark.parametrize("field, value", [("omega_b_deg_s", float("nan")), ("omega_b_deg_s", None),
                                          ("omega_b_deg_s", 1e400), ("stderr_deg_s", float("inf")),
                                          ("stderr_deg_s", -5.0), ("unstable", "yes"), ("omega_b_deg_s", "missing")])
def test_item13_a_cache_line_with_a_bad_field_is_skipped_naming_file_and_line(tmp_path, field, value):
    import json as js

    from plate_env.run import sweeps
    from plate_env.run.executor import BackendSpec

    backend = BackendSpec.of("atlas")
    specs = _atlas_specs()
    cache = tmp_path / "c.jsonl"
    good = sweeps.run_cached(backend, specs, cache, chunk=1, progress=False)
    lines = cache.read_text().splitlines()
    d = js.loads(lines[1])
    if value == "missing":
        del d[field]
    else:
        d[field] = value
    lines[1] = js.dumps(d).replace("1e+400", "1e400")
    cache.write_text("\n".join(lines) + "\n")
    with pytest.warns(UserWarning, match=rf"c\.jsonl: line 2: {field}"):
        again = sweeps.run_cached(backend, specs, cache, chunk=1, progress=False)
    def outcome(rs):
        return [(r.omega_b_deg_s, r.stderr_deg_s, r.unstable, r.reason) for r in rs]

    assert outcome(again) == outcome(good)  # the bad record was not loaded: its probe ran again


def test_item10_every_output_path_is_checked_before_the_bench_runs(capsys):
    from plate_env.cli import main

    code = main(["bench", "--suite", "atlas-v0", "--agent", "grid", "--limit", "1", "--no-cache", "--no-progress",
                 "--markdown", "/nonexistent/x.md", "--plot", "p.png"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and "--markdown '/nonexistent/x.md'" in err and err.count("\n") == 1


# ------------------------------------------------------------------------------------------- 13-15: blame
def test_item14_a_pool_size_in_other_digits_is_refused_by_name():
    from plate_env.run.executor import check_executor_name

    with pytest.raises(ValueError, match="pool:N needs a positive number"):
        check_executor_name("pool:²")


@pytest.mark.parametrize("argv, needle", [
    (["--method", "lorentz", "--physics", "garbage"], "--physics 'garbage'"),
    (["--method", "lorentz", "--mass-g", "5"], "--mass-g applies to --method atlas only"),
    (["--method", "lorentz", "--forward", "lab"], "--forward applies to --method atlas only"),
    (["--method", "lorentz", "--bp", "2", "--diameter-mm", "60"], "--bp, --diameter-mm apply to --method atlas"),
    (["--physics", "tilelink"], "--physics applies to --method lorentz only"),
    (["--model", "pointmass"], "--model applies to --method lorentz only")])
def test_item15_fit_options_the_method_ignores_are_refused(tmp_path, capsys, argv, needle):
    from plate_env.cli import main

    csv = tmp_path / "s.csv"
    csv.write_text("f_p_hz,omega_b_deg_s\n20,100\n25,200\n30,100\n")
    assert main(["fit", str(csv), "--amp", "3", *argv]) == 2
    assert needle in capsys.readouterr().err


# ------------------------------------------------------------------------------------------- 16-17: parsers
def test_item16_bench_json_is_strict_json(capsys):
    from plate_env.cli import main

    def strict(text):
        def refuse(name):
            raise ValueError(f"non-standard JSON constant {name}")

        return json.loads(text, parse_constant=refuse)

    # the grid agent's short episode ends with no estimate: its error is not a number (main 284a76f: Infinity)
    assert main(["bench", "--suite", "atlas-v0", "--agent", "grid", "--limit", "1", "--no-cache", "--no-progress",
                 "--json"]) == 0
    board = strict(capsys.readouterr().out)
    assert board["non_finite"], board  # what was not a number is named
    from plate_env.cli import strict_json

    text = strict_json({"summaries": {"grid": {"p90_error": math.inf, "median_error": 0.1}}, "x": [math.nan, 1.0]})
    d = strict(text)
    assert d["summaries"]["grid"] == {"p90_error": None, "median_error": 0.1} and d["x"] == [None, 1.0]
    assert d["non_finite"] == ["summaries.grid.p90_error", "x[0]"]


# ------------------------------------------------------------------------------------------- 19-23: newcomers
def test_item19_version_and_defaults_in_help(capsys):
    from plate_env.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("plate-env ")
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: 10:40:1)" in text and "(default: tilelink)" in text and "(default: 3.0)" in text


def test_item19_21_sweep_writes_the_csv_fit_reads_and_shows_no_omega_b_for_unstable_probes(tmp_path, capsys):
    from plate_env.cli import main
    from plate_env.core.probe_table import read_lab_csv

    csv = tmp_path / "out.csv"
    assert main(["sweep", "--physics", "atlas", "--omega-n", "10pi", "--alpha", "36.9", "--freqs", "10:40:1",
                 "--no-progress", "--csv", str(csv)]) == 0
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines() if line.strip()[:1].isdigit() and "stable" in line]
    assert len(rows) == 31
    unstable = [r for r in rows if "unstable:" in r]
    assert 0 < len(unstable) < 31
    for r in rows:  # one rule: an unstable probe shows no omega_B, a stable one its value
        assert (r[1], r[2]) == ("-", "-") if "unstable:" in r else float(r[1]) > 0, r
    table = read_lab_csv(csv)
    assert list(table.f_p_hz) == list(np.arange(10.0, 40.5, 1.0)) and table.unstable.sum() == len(unstable)
    assert main(["fit", str(csv), "--forward", "tilelink/pointmass"]) == 0  # the CSV fit reads, fitted
    out = capsys.readouterr().out
    assert "68 % interval" in out and "95 % interval" in out


def test_item20_an_error_says_each_reason_once(tmp_path, capsys):
    from plate_env.cli import main

    csv = tmp_path / "s.csv"
    csv.write_text("f_p_hz,omega_b_deg_s\n20,100\n25,200\n30,100\n")
    assert main(["fit", str(csv), "--amp", "3", "--mass-g", "100"]) == 2
    err = capsys.readouterr().err
    parts = [part.strip() for part in err.split(";")]
    assert len(parts) == len(set(parts)), err  # no reason twice, whatever its wording (main: one sentence 11 times)
    assert err.count("plate-env build atlas") == 1 and err.count("\n") == 1 and len(err) < 700, err


def test_item23_a_pool_larger_than_the_machine_is_capped_with_a_note():
    import os

    from plate_env.run.executor import make_executor

    with pytest.warns(UserWarning, match="CPU cores; using"):
        ex = make_executor("pool:1000")
    try:
        assert ex.workers == (os.cpu_count() or 1)
    finally:
        ex.close()


@pytest.mark.parametrize("spec, needle", [("grid:n=abc", "agent 'grid:n=abc'"), ("grid:foo=1", "agent 'grid:foo=1'"),
                                          ("{syntax}:A", "cannot be imported: SyntaxError"),
                                          ("{imports}:A", "cannot be imported: ModuleNotFoundError"),
                                          ("{raises}:A", "cannot be imported: RuntimeError"),
                                          ("{exits}:A", "cannot be imported: SystemExit"),
                                          ("{needs}:A", "cannot be made without arguments")])
def test_item14_bad_agent_specs_are_one_line_naming_the_agent(tmp_path, capsys, spec, needle):
    from plate_env.cli import main

    files = {"syntax": "def (:\n", "imports": "import no_such_module_xyz\n", "raises": "raise RuntimeError('boom')\n",
             "exits": "import sys\nsys.exit(3)\n",
             "needs": "class A:\n    def __init__(self, x):\n        pass\n    def next_probe(self, h, o=None):\n"
                      "        return None\n"}
    for name, text in files.items():
        (tmp_path / f"{name}.py").write_text(text)
    spec = spec.format(**{k: str(tmp_path / f"{k}.py") for k in files})
    assert main(["bench", "--suite", "atlas-v0", "--agent", spec, "--limit", "1", "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1 and "internal error" not in err, err


# ------------------------------------------------------------------------------------------- 18: security
def _doctored_zip(tmp_path, change) -> str:
    import zipfile

    from plate_env_agents.ppo import DEFAULT_MODEL

    out = tmp_path / "model.zip"
    with zipfile.ZipFile(DEFAULT_MODEL) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.namelist():
            blob = src.read(item)
            if item == "data":
                d = json.loads(blob)
                change(d)
                blob = json.dumps(d).encode()
            dst.writestr(item, blob)
    return str(out)


def test_item18_a_model_zip_never_gets_its_pickled_code_run(tmp_path):
    import base64
    import pickle

    from plate_env_agents.ppo import PPOAgent

    marker = tmp_path / "pwned"

    class Evil:
        def __reduce__(self):
            return (marker.write_text, ("ran",))

    def add_evil(d):
        d["policy_class"] = {":type:": "<class 'abc.ABCMeta'>",
                             ":serialized:": base64.b64encode(pickle.dumps(Evil())).decode(),
                             "__init__": "<function ActorCriticPolicy.__init__ at 0x0>"}

    try:
        agent = PPOAgent(_doctored_zip(tmp_path, add_evil), deterministic=False)
        agent.model  # noqa: B018 - loads through SB3
    finally:  # SB3 alone unpickles the policy class and runs Evil (main 284a76f: then fails on the int it returned)
        assert not marker.exists(), "the zip's pickled code ran"
    # a pickled field the loader does not know is never read (issue 38 item 4: nothing in data is unpickled)
    PPOAgent(_doctored_zip(tmp_path, lambda d: d.update(surprise=d["policy_class"])), deterministic=False)
    assert not marker.exists(), "the zip's pickled code ran"


def test_item14_18_a_model_for_another_space_or_algorithm_is_one_line(tmp_path, capsys):
    from plate_env.cli import main

    def other_space(d):
        d["observation_space"]["_shape"] = [17]

    spec = "sb3:" + _doctored_zip(tmp_path, other_space)
    assert main(["bench", "--suite", "atlas-v0", "--agent", spec, "--limit", "1", "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert "not PlateRotation-v0's" in err and err.count("\n") == 1
    from plate_env_agents.ppo import DEFAULT_MODEL

    assert main(["bench", "--suite", "atlas-v0", "--agent", f"sb3:sac:{DEFAULT_MODEL}", "--limit", "1",
                 "--no-cache"]) == 2
    err = capsys.readouterr().err
    assert "ActorCriticPolicy policy, not the SACPolicy" in err and err.count("\n") == 1


def test_item11_fit_refuses_more_rows_than_its_documented_limit_before_any_work(tmp_path, capsys):
    from plate_env.cli import MAX_FIT_ROWS, main

    csv = tmp_path / "big.csv"
    n = MAX_FIT_ROWS + 1
    csv.write_text("f_p_hz,omega_b_deg_s\n" + "".join(f"{10 + 30 * i / n:.4f},100\n" for i in range(n)))
    assert main(["fit", str(csv), "--amp", "3"]) == 2
    err = capsys.readouterr().err
    assert f"{n} rows; at most {MAX_FIT_ROWS} are read" in err


def test_item19_make_agent_takes_the_specs_bench_takes():
    from plate_env_agents import make_agent
    from plate_env_agents.ppo import DEFAULT_MODEL, PPOAgent

    agent = make_agent(f"sb3:{DEFAULT_MODEL}")
    assert isinstance(agent, PPOAgent) and agent.path == DEFAULT_MODEL
    assert make_agent("grid:n=7").n == 7


def _sigint_handler(_item):
    import signal

    return [signal.getsignal(signal.SIGINT) == signal.SIG_IGN]


def test_item23_pool_workers_leave_ctrl_c_to_the_driver():
    """Ctrl-C reaches every process of the group: a worker that ignores it prints no KeyboardInterrupt traceback;
    the driver keeps the finished chunks and ends the workers."""
    from plate_env.run.executor import make_executor

    ex = make_executor("pool:1")
    try:
        assert [r for _, r in ex.map(_sigint_handler, [1])] == [[True]]
    finally:
        ex.close()


def test_item9_a_read_only_install_and_home_compile_the_kernels_in_memory(tmp_path, monkeypatch):
    """numba's cache=True with no writable place refuses to define a kernel ("no locator available"): the kernels
    then compile in memory, with one warning; a NUMBA_CACHE_DIR that is not writable is named as numba's."""
    import numba

    from plate_env.physics.tilelink import jit_cache

    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    ro_src = tmp_path / "pkg"
    ro_src.mkdir()
    (ro_src / "k.py").write_text("")
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.setenv("XDG_CACHE_HOME", str(home / ".cache"))
    assert jit_cache.can_cache(ro_src / "k.py") == (True, None)
    ro_src.chmod(0o555)
    home.chmod(0o555)
    try:
        import os

        if os.access(ro_src, os.W_OK):  # root ignores permission bits: make the check see a read-only tree
            monkeypatch.setattr(jit_cache, "_writable_dir", lambda path: False)
        usable, why = jit_cache.can_cache(ro_src / "k.py")
        assert not usable and "compile in memory" in why and "NUMBA_CACHE_DIR" in why
        numba.njit(cache=usable)(lambda x: x + 1)(1)  # what the kernels do with it: defined and run
        monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "full"))
        usable, why = jit_cache.can_cache(ro_src / "k.py")
        assert not usable and "numba's compilation cache" in why
    finally:
        ro_src.chmod(0o755)
        home.chmod(0o755)
    from plate_env.physics.tilelink import kernels

    assert kernels.CACHE is jit_cache.CACHE


def _slow_item(item):
    import time

    time.sleep(60)
    return item


#: A pool sweep's driver, Ctrl-C'd after 3 s (``{send}``: how the SIGINT is sent), in a fresh interpreter: inside the
#: full suite's process, after the other test files, the same code saw no KeyboardInterrupt (cause not found: the
#: SIGINT handler and the thread's signal mask were unchanged), so the test runs what a user runs, a new process.
_CTRL_C_DRIVER = """
import os, signal, sys, threading, time
sys.path.insert(0, {tests!r})
from test_hardening import _slow_item
from plate_env.run.executor import make_executor

# what a user's terminal gives the process: started in the background (CI, `cmd &`), it inherits SIGINT ignored
signal.signal(signal.SIGINT, signal.default_int_handler)
ex = make_executor("pool:1")
it = ex.map(_slow_item, [1, 2])
timer = threading.Timer(3.0, lambda: {send})
t0 = time.perf_counter()
timer.start()
try:
    next(it)
    print("no interrupt", time.perf_counter() - t0)
except KeyboardInterrupt:
    pids = ex.worker_pids()
    ex.close()
    print("interrupted", time.perf_counter() - t0, len(pids))
"""


def _ctrl_c_a_pool_sweep(send: str) -> tuple[str, float, int]:
    import subprocess
    import sys
    from pathlib import Path

    code = _CTRL_C_DRIVER.format(tests=str(Path(__file__).parent), send=send)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=180).stdout.split()
    if out[0] == "interrupted":
        return out[0], float(out[1]), int(out[2])
    return out[0], float(out[-1]), -1


def test_item12_ctrl_c_ends_a_pool_sweep_without_waiting_for_running_chunks():
    """Ctrl-C while pool workers run long chunks (rigid_limit sweeps run in a pool): the driver ends the workers at
    once instead of waiting for their chunks (25-49 s before)."""
    what, elapsed, live = _ctrl_c_a_pool_sweep("os.kill(os.getpid(), signal.SIGINT)")
    assert what == "interrupted" and elapsed < 20.0 and live == 0, (what, elapsed, live)


def test_item12_ctrl_c_that_lands_on_another_thread_still_ends_a_pool_sweep():
    """The kernel may hand a process's Ctrl-C to any of its threads: here to the timer's own thread. The driver must
    still see it within a poll, not when the running chunk ends (it waited 60 s: the wait blocked in C)."""
    what, elapsed, _ = _ctrl_c_a_pool_sweep("signal.pthread_kill(threading.get_ident(), signal.SIGINT)")
    assert what == "interrupted" and elapsed < 20.0, (what, elapsed)


@pytest.mark.parametrize("body, needle", [("raise RuntimeError('agent bug')", "failed in next_probe: RuntimeError"),
                                          ("return None", "stopped before its first probe"),
                                          ("import sys; sys.exit(5)", "failed in next_probe: SystemExit")])
def test_item14_an_agent_that_fails_during_the_bench_is_one_line_naming_it(tmp_path, capsys, body, needle):
    from plate_env.cli import main

    (tmp_path / "ag.py").write_text("from plate_env.env.protocol import Agent\n\n\nclass A(Agent):\n"
                                    "    name = 'mine'\n\n    def next_probe(self, history, obs=None):\n"
                                    f"        {body}\n")
    argv = ["bench", "--suite", "atlas-v0", "--agent", f"{tmp_path / 'ag.py'}:A", "--limit", "1", "--no-cache",
            "--no-progress", "--json"]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == "" and "agent 'mine'" in err and needle in err and err.count("\n") == 1, err


def test_item14_17_what_an_agent_prints_during_the_bench_goes_to_stderr(tmp_path, capsys):
    from plate_env.cli import main

    (tmp_path / "ag.py").write_text("from plate_env_agents.grid import GridAgent\n\n\nclass A(GridAgent):\n"
                                    "    def next_probe(self, history, obs=None):\n"
                                    "        print('chatty agent')\n"
                                    "        return super().next_probe(history, obs)\n")
    argv = ["bench", "--suite", "atlas-v0", "--agent", f"{tmp_path / 'ag.py'}:A", "--limit", "1", "--no-cache",
            "--no-progress", "--json"]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    json.loads(out)  # one document, nothing else
    assert "chatty agent" in err


#: A plug-in agent whose output bypasses Python's sys.stdout: a write on file descriptor 1 and C's printf (buffered
#: in C's stdio while fd 1 is a pipe or file, flushed later).
CHATTY_BELOW_PYTHON = ("import ctypes\nimport os\n\nfrom plate_env_agents.grid import GridAgent\n\n\n"
                       "class A(GridAgent):\n    def next_probe(self, history, obs=None):\n"
                       "        os.write(1, b'fd1 from the agent\\n')\n"
                       "        ctypes.CDLL(None).printf(b'printf from the agent\\n')\n"
                       "        return super().next_probe(history, obs)\n")


def _strict(out: str):
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(out, parse_constant=refuse)


@pytest.mark.parametrize("command", ["bench", "identify"])
def test_item17_writes_below_python_during_an_agent_run_go_to_stderr(tmp_path, capfd, monkeypatch, command):
    """fd-level output (C code, an agent's os.write(1, ...), child processes) during the agents' runs lands on
    stderr; stdout is one strict JSON document. Before: bench redirected Python's sys.stdout only, identify nothing."""
    from plate_env.cli import main

    (tmp_path / "ag.py").write_text(CHATTY_BELOW_PYTHON)
    if command == "bench":
        argv = ["bench", "--suite", "atlas-v0", "--agent", f"{tmp_path / 'ag.py'}:A", "--limit", "1", "--no-cache",
                "--no-progress", "--json"]
    else:  # identify takes the shipped agents: the grid agent made as chatty
        import ctypes
        import os

        import plate_env_agents.grid as grid

        real = grid.GridAgent.next_probe

        def chatty(self, history, obs=None):
            os.write(1, b"fd1 from the agent\n")
            ctypes.CDLL(None).printf(b"printf from the agent\n")
            return real(self, history, obs)

        monkeypatch.setattr(grid.GridAgent, "next_probe", chatty)
        argv = ["identify", "--physics", "atlas", "--agent", "grid", "--omega-n", "10pi", "--alpha", "45", "--json"]
    code = main(argv)
    out, err = capfd.readouterr()
    assert code in (0, 1)
    _strict(out)  # one document, nothing else
    assert "fd1 from the agent" in err and "printf from the agent" in err


def test_item17_writes_below_python_during_a_sweep_go_to_stderr(capfd, monkeypatch):
    """What the physics or its workers write on fd 1 during a sweep (here: the sweep runner itself) lands on stderr;
    stdout is the result (--json: one strict JSON document). Before: the sweep redirected nothing."""
    import os

    from plate_env.cli import main
    from plate_env.run import sweeps

    real = sweeps.run_cached

    def chatty(*args, **kwargs):
        os.write(1, b"fd1 from the physics\n")
        return real(*args, **kwargs)

    monkeypatch.setattr(sweeps, "run_cached", chatty)
    assert main(["sweep", "--physics", "atlas", "--freqs", "15,20", "--no-progress", "--json"]) == 0
    out, err = capfd.readouterr()
    assert len(_strict(out)["probes"]) == 2 and "fd1 from the physics" in err


def test_item14_a_subnormal_frequency_step_is_refused_by_name(capsys):
    from plate_env.cli import main

    assert main(["sweep", "--physics", "atlas", "--freqs", "10:40:1e-320", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--freqs '10:40:1e-320'" in err and "at most 2000" in err


def test_item11_exact_repeats_are_computed_once_and_give_the_per_row_likelihood(monkeypatch):
    """30 exact copies of each row of a sweep (plus rows at the same frequencies with other omega_B, which are not
    merged): the likelihood evaluates each distinct row once, and equals the sum of the rows' own terms."""
    from plate_env.identify import inference

    fm = load_forward_model("tilelink/pointmass")
    m = fm.members[0]
    base = _honest_sweep(31.4, 40.0, 3.0, seed=3)
    other = ProbeTable.from_arrays(base.f_p_hz, base.a_p_deg, base.omega_b_deg_s * 1.01 + 0.5, base.stderr_deg_s,
                                   base.unstable)
    table = ProbeTable.concat(*([base] * 30), other)
    assert inference.distinct_probes(table) == 2 * len(base)
    w, a = fm.grid(inference.N_OMEGA, inference.N_ALPHA)
    calls = []
    real = inference.probe_log_likelihood
    monkeypatch.setattr(inference, "probe_log_likelihood", lambda *x: calls.append(1) or real(*x))
    ll, skipped = inference.member_log_likelihood(m, table, w, a)
    assert len(calls) == 2 * len(base) and skipped == 0
    monkeypatch.setattr(inference, "probe_log_likelihood", real)
    # the reference: every row's own term, summed row by row (what main computed)
    ref = sum(inference.member_log_likelihood(m, table, w, a, only=np.arange(len(table)) == k)[0]
              for k in range(len(table)))
    finite = np.isfinite(ref)
    assert np.array_equal(finite, np.isfinite(ll))
    np.testing.assert_allclose(ll[finite], ref[finite], rtol=1e-9, atol=1e-6)


def test_item11_fit_says_on_stderr_what_a_long_fit_computes(tmp_path, capsys):
    from plate_env.cli import FIT_PROGRESS_ROWS, main

    base = _honest_sweep(31.4, 40.0, 3.0, seed=3)
    rows = "".join(f"{f:.4f},{0.0 if u else y:.4f},{e:.4f},{int(u)}\n" for f, y, e, u in
                   zip(base.f_p_hz, base.omega_b_deg_s, base.stderr_deg_s, base.unstable, strict=True))
    copies = -(-FIT_PROGRESS_ROWS // len(base))
    csv = tmp_path / "repeats.csv"
    csv.write_text("f_p_hz,omega_b_deg_s,stderr_deg_s,unstable\n" + rows * copies)
    assert main(["fit", str(csv), "--amp", "3", "--forward", "tilelink/pointmass", "--json"]) in (0, 1)
    out, err = capsys.readouterr()
    json.loads(out)
    assert f"fit: {copies * len(base)} rows, {len(base)} distinct" in err and "fit: done in" in err


def _plotted_lines(monkeypatch, table, est, fm):
    """The lines plot_fit draws on its data axes (the figure is captured, not written)."""
    import plate_env.plotting as plotting

    figs = []
    monkeypatch.setattr(plotting, "save_figure", lambda fig, path, dpi=100: figs.append(fig))
    plotting.plot_fit(table, est, "unused.png", fm)
    return figs[0].axes[0].get_lines()


def test_item19_atlas_plots_draw_the_forward_models_curve_at_the_estimate(monkeypatch):
    from plate_env.identify.inference import identify_atlas

    fm = load_forward_model("tilelink/pointmass")
    table = _honest_sweep(31.4, 40.0, 3.0, seed=3)
    est = identify_atlas(table, fm)
    assert est.ok
    curves = [ln for ln in _plotted_lines(monkeypatch, table, est, fm) if "at the estimate" in str(ln.get_label())]
    assert len(curves) == 1
    f, y = (np.asarray(v, float) for v in curves[0].get_data())
    assert f.min() == table.f_p_hz.min() and f.max() == table.f_p_hz.max()
    m = fm.members[0]
    mean, _, p_un = m.atlas.predict(f, 3.0, est.omega_n, est.alpha)
    drawn = p_un < 0.5  # the curve is drawn where the model predicts stable probes only (issue 40 item 2)
    assert drawn.any() and np.isnan(y[~drawn]).all()
    np.testing.assert_allclose(y[drawn], mean[drawn], rtol=1e-9)
    # the curve the estimate promises follows the data: the stable probes' median miss is within a few model scales
    st = ~table.unstable & (np.interp(table.f_p_hz, f, drawn.astype(float)) == 1.0)
    at = np.interp(table.f_p_hz[st], f[drawn], y[drawn])
    scale = np.sqrt(m.atlas.predict(table.f_p_hz[st], 3.0, est.omega_n, est.alpha)[1] ** 2 + m.sigma_model ** 2)
    assert np.median(np.abs(table.omega_b_deg_s[st] - at) / scale) < 2.0
    # no estimate: no curve claimed
    bad = identify_atlas(ProbeTable.from_arrays(table.f_p_hz, 3.0, 100 * table.omega_b_deg_s, table.stderr_deg_s,
                                                table.unstable), fm)
    assert not bad.ok
    assert not [ln for ln in _plotted_lines(monkeypatch, table, bad, fm) if "at the estimate" in str(ln.get_label())]


def test_item19_fit_and_identify_plots_get_the_forward_model(tmp_path, monkeypatch, capsys):
    import plate_env.plotting as plotting
    from plate_env.cli import main

    got = []
    monkeypatch.setattr(plotting, "plot_fit", lambda table, est, path, fm=None, **kw: got.append((est, fm)))
    base = _honest_sweep(31.4, 40.0, 3.0, seed=3)
    csv = tmp_path / "s.csv"
    csv.write_text("f_p_hz,omega_b_deg_s,stderr_deg_s,unstable\n" + "".join(
        f"{f:.4f},{0.0 if u else y:.4f},{e:.4f},{int(u)}\n"
        for f, y, e, u in zip(base.f_p_hz, base.omega_b_deg_s, base.stderr_deg_s, base.unstable, strict=True)))
    assert main(["fit", str(csv), "--amp", "3", "--forward", "tilelink/pointmass", "--plot",
                 str(tmp_path / "f.png")]) == 0
    assert main(["identify", "--physics", "atlas", "--omega-n", "10pi", "--alpha", "45", "--seed", "0",
                 "--plot", str(tmp_path / "i.png")]) == 0
    capsys.readouterr()
    for est, fm in got:
        assert est.ok and fm is not None and fm.members and est.forward == fm.name


@pytest.mark.parametrize("field, value", [
    ("omega_n_true", float("nan")), ("omega_n_true", None), ("omega_n_true", "missing"), ("omega_n_true", 1e400),
    ("probe_sim_s", [float("inf")]), ("wall_s", -5.0), ("prefix.omega_n", float("nan")),
    ("prefix.ci95", [0.0, float("inf")]), ("probes.stderr_deg_s", float("inf")), ("probes.stderr_deg_s", -5.0),
    ("probes.omega_b_deg_s", None)])
def test_item13_a_bench_cache_line_with_a_bad_field_is_skipped_naming_file_and_line(tmp_path, field, value):
    import json as js

    from plate_env.bench.runner import evaluate
    from plate_env_agents import make_agent

    cache = tmp_path / "b.jsonl"
    good = evaluate(make_agent("grid"), "atlas-v0", cache=cache, limit=2)
    import warnings

    with warnings.catch_warnings():  # the records bench writes load without a warning
        warnings.simplefilter("error", UserWarning)
        evaluate(make_agent("grid"), "atlas-v0", cache=cache, limit=2)
    lines = cache.read_text().splitlines()
    d = js.loads(lines[1])
    name = field.split(".")[-1]
    if field.startswith("prefix."):
        d["prefix"][0][name] = value
    elif field.startswith("probes."):
        d["probes"][0][{"omega_b_deg_s": 2, "stderr_deg_s": 3}[name]] = value
    elif value == "missing":
        del d[field]
    elif field == "probe_sim_s":
        d[field][0] = value[0]
    else:
        d[field] = value
    lines[1] = js.dumps(d).replace("1e+400", "1e400")
    cache.write_text("\n".join(lines) + "\n")
    with pytest.warns(UserWarning, match=rf"b\.jsonl: line 2: \S*{name}"):
        again = evaluate(make_agent("grid"), "atlas-v0", cache=cache, limit=2)
    assert [e.omega_n_true for e in again.episodes] == [e.omega_n_true for e in good.episodes]
    assert ([[x.omega_n for x in e.prefix] for e in again.episodes]
            == [[x.omega_n for x in e.prefix] for e in good.episodes])  # the bad record's episode ran again


class _InterruptedSubmit:
    """A process pool whose second ``submit`` is hit by Ctrl-C (on a busy machine the driver spends seconds spawning
    workers inside ``submit``, where a SIGINT lands as KeyboardInterrupt)."""

    def __init__(self, pool) -> None:
        self.pool, self.calls = pool, 0
        self._processes = pool._processes

    def submit(self, fn, item):
        self.calls += 1
        if self.calls == 2:
            raise KeyboardInterrupt
        fut = self.pool.submit(fn, item)
        self._processes = self.pool._processes
        return fut

    def shutdown(self, **kw) -> None:
        self.pool.shutdown(**kw)


def test_item12_ctrl_c_during_submit_still_ends_the_running_workers():
    """Before: a KeyboardInterrupt raised while chunks were being submitted left the started worker running its chunk
    (60 s here) and ``close`` waited for it."""
    import time

    from plate_env.run.executor import make_executor

    ex = make_executor("pool:1")
    new_pool = ex._new_pool
    ex._new_pool = lambda: _InterruptedSubmit(new_pool())
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        next(ex.map(_slow_item, [1, 2]))
    assert ex.worker_pids() == []
    ex.close()
    assert time.perf_counter() - t0 < 30.0
