"""Issue 37: one estimate contract for every method (uncalibrated, calibrated, Lorentz) and agent: data the model
cannot explain and objects outside the identifiable range get no estimate or a stated bound
(plate_env.identify.estimators: gated, gated_unknown_origin). Each item test fails before its fix."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, example, given, settings
from hypothesis import strategies as st

from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify

F_HZ = np.arange(10.0, 41.0, 2.0)


def _table(values, se: float = 2.0) -> ProbeTable:
    """A 3-deg sweep of ``values`` (deg/s), every probe stable (zeros measured, as a CSV of zeros says)."""
    v = np.asarray(values, dtype=float)
    return ProbeTable.from_arrays(F_HZ, np.full(F_HZ.size, 3.0), v, np.full(F_HZ.size, se), np.zeros(F_HZ.size, bool))


#: Every estimator a user or an agent can reach on 3-deg data of unknown origin or of the point mass, as identify()'s
#: arguments (identify(table, ...) is make_estimator(method, ForwardName(physics, model), None, forward,
#: calibration).fit(table); through identify the property also runs on code from before the estimator objects).
ESTIMATORS = {"atlas lab": dict(method="atlas", physics="tilelink", model="pointmass", forward="lab"),
              "atlas tilelink/pointmass": dict(method="atlas", physics="tilelink", model="pointmass"),
              "lorentz paper": dict(method="lorentz", physics="paper", model="pointmass"),
              "lorentz lab": dict(method="lorentz", physics="lab", model="lab"),
              "lorentz tilelink/pointmass": dict(method="lorentz", physics="tilelink", model="pointmass"),
              "calibrated paper": dict(calibration="paper")}


def _fit(which: str, table: ProbeTable):
    return identify(table, **ESTIMATORS[which])


@pytest.mark.parametrize("data", ["zeros", "negative", "flat", "noise"])
def test_item3_the_calibrated_path_refuses_what_it_cannot_explain(data):
    """`fit zeros.csv --calibration paper` answered 3.3 pi (ok, "check": null); noise 4.8 pi; now no estimate, the
    lab model's check carried and the missing resonance named."""
    values = {"zeros": np.zeros(F_HZ.size), "negative": -20.0 * F_HZ, "flat": np.full(F_HZ.size, 300.0),
              "noise": np.random.default_rng(0).uniform(0.0, 800.0, F_HZ.size)}[data]
    est = identify(_table(values), calibration="paper")
    assert not est.ok and est.method == "calibrated" and est.check is not None and not est.check.passed
    assert "no calibrated reading of these probes" in est.reason and "no resonance" in est.reason


def test_item3_a_calibrated_reading_carries_its_check():
    from plate_env.identify.fitting import lorentzian

    f = np.arange(14.0, 34.01, 1.0)  # the paper's Fig. 7a curve: no model explains it, its hump is read
    t = ProbeTable.from_arrays(f, np.full(f.size, 3.0), lorentzian(f, 598.7, 25.1, 5.1), np.full(f.size, 10.0))
    est = identify(t, calibration="paper")
    assert est.ok and est.check is not None and est.check.to_dict()["member"]


def test_contract_the_lorentz_lines_on_noise_are_no_estimate():
    """`fit noise.csv --method lorentz` answered 26.9 pi (interval 0-...); now no estimate."""
    est = identify(_table(np.random.default_rng(0).uniform(0.0, 800.0, F_HZ.size)), method="lorentz",
                   physics="paper", model="pointmass")
    assert not est.ok and "no resonance" in est.reason and "R^2" in est.reason


def test_contract_a_lorentz_read_of_simulated_data_passes_its_models_check():
    """The grid agent's Lorentz estimate in an env goes through the posterior of the model that made the data:
    honest point-mass sweeps keep their estimate and carry the check they passed."""
    from plate_env.env import PlateRotationEnv
    from plate_env.env.episode import run_episode
    from plate_env_agents import make_agent

    env = PlateRotationEnv(physics="atlas")
    res = [run_episode(env, make_agent("grid"), seed=s) for s in range(3)]
    assert any(r.estimate.ok for r in res)
    for r in res:
        assert r.estimate.check is not None or not r.estimate.ok
        if r.estimate.ok:
            assert r.estimate.check.passed


def _garbage(kind: str, level: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return {"zeros": np.zeros(F_HZ.size), "constant": np.full(F_HZ.size, level),
            "negative": -level * (0.5 + rng.uniform(size=F_HZ.size)),
            "noise": rng.uniform(0.0, level, F_HZ.size),
            "falling": level * (F_HZ[::-1] / F_HZ[-1]) ** 3}[kind]


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow],
          phases=[Phase.explicit, Phase.generate])  # no shrinking: each example is seconds of posteriors
@given(kind=st.sampled_from(["zeros", "constant", "negative", "noise", "falling"]),
       level=st.floats(50.0, 1500.0), seed=st.integers(0, 2 ** 16), which=st.sampled_from(sorted(ESTIMATORS)))
def test_contract_property_no_estimator_reads_data_no_model_explains(kind, level, seed, which):
    """Property over sweeps no disc makes (zeros, a constant, negative, uniform noise, a monotone fall from 10 Hz)
    and every estimator: an estimate only with the model's predictive check passed (the contract), and for the
    Lorentz method only of a measured hump. (Whether the check refuses every such sweep is its power: a constant
    100 deg/s passes the lab model's check at p 0.0015 and is read through a calibration; issue 38 owns the check.)"""
    est = _fit(which, _table(_garbage(kind, level, seed)))
    if est.ok:
        assert est.check is not None and est.check.passed, f"{which} read {kind} without a passed check"
        if est.method == "lorentz":
            from plate_env.identify.estimators import hump_reason

            assert hump_reason(_table(_garbage(kind, level, seed))) is None


def test_contract_the_estimators_are_the_only_way_in():
    """The env, identify() and the episode loop make their estimates through the same estimator classes (no
    method string reaches the fit): a Lorentz estimator with the paper's lines is gated like any other."""
    from plate_env.identify.estimators import ForwardName, LorentzEstimator

    est = LorentzEstimator(ForwardName("paper", "pointmass")).fit(_table(np.zeros(F_HZ.size)))
    assert not est.ok


# ------------------------------------------------------------------------------------------------ live physics
#: The tilelink/pointmass atlas's identifiable range (pi rad/s): outside it the contract asks for no estimate or a
#: bound.
RANGE_PI = (1.4, 45.0)
AGENTS = ("grid", "coarse_to_fine", "bayes", "ppo")


def _episode(agent: str, omega_pi: float, seed: int, alpha_deg: float = 45.0, **env_kwargs):
    import gymnasium as gym

    from plate_env.env.episode import run_episode
    from plate_env_agents import make_agent

    env = gym.make("PlateRotation-v0", **{"physics": "tilelink", **env_kwargs})
    try:
        return run_episode(env, make_agent(agent), seed=seed, options={"omega_n": omega_pi * math.pi,
                                                                       "alpha": math.radians(alpha_deg)}).estimate
    finally:
        env.close()


def _holds(est, omega_pi: float, where: str) -> None:
    """The contract on one live episode: an object outside the identifiable range gets no estimate (a bound, when
    stated, on the truth's side); an estimate inside it is a number inside the range."""
    truth = omega_pi * math.pi
    if not RANGE_PI[0] <= omega_pi <= RANGE_PI[1]:
        assert not est.ok, f"{where}: {omega_pi:.3g} pi read as {est.omega_n / math.pi:.3g} pi, 95 % " \
                           f"[{est.omega_n_ci95[0] / math.pi:.3g}, {est.omega_n_ci95[1] / math.pi:.3g}] pi"
    if est.bound is not None:
        side, x = est.bound
        assert (truth > x) if side == "above" else (truth < x), f"{where}: bound {side} {x / math.pi:.3g} pi " \
                                                                 f"excludes the truth {omega_pi:.3g} pi"


@pytest.mark.parametrize(("agent", "omega_pi", "seed"), [
    ("coarse_to_fine", 60.0, 0),  # the issue's: 27.4 pi [25.9, 29.1] pi at 5860216 and at 893bbe6
    ("coarse_to_fine", 60.0, 1),  # 27.7 pi
    ("coarse_to_fine", 1.0, 0),  # 1.51 pi
    ("ppo", 200.0, 0),  # 1.65 pi [1.47, 1.85] pi
    ("ppo", 60.0, 1),  # 18.9 pi
    ("coarse_to_fine", 0.5, 1),  # 1.97 pi
])
def test_item1_objects_outside_the_range_get_no_estimate_or_a_true_bound(agent, omega_pi, seed):
    """Fixed objects outside 1.4-45 pi whose probes an in-range alias explains (the predictive check passes): each
    answered a confident in-range number before the extended-range test
    (plate_env.identify.identifiability); now no estimate, with a bound on the truth's side."""
    est = _episode(agent, omega_pi, seed)
    _holds(est, omega_pi, f"{agent} seed {seed}")
    assert "cannot tell" in est.reason or "range" in est.reason


def test_item1_a_bound_holds_whichever_posterior_the_object_follows():
    """tilelink-v0 object 37 (27.74 pi, alpha 55 deg) by coarse_to_fine: the in-range posterior read 34.8 pi, its 95 %
    interval holding the truth, while the extended one put 0.97 above 45 pi with its 2.5 % quantile at 38.2 pi; that
    quantile alone was a false bound ("omega_n > 38.2 pi"). The bound is the lower of the two quantiles."""
    from plate_env.bench.suites import load_suite

    suite = load_suite("tilelink-v0")
    obj = suite.objects[37]
    est = _episode("coarse_to_fine", obj.omega_n / math.pi, obj.seed, math.degrees(obj.alpha), **suite.env_kwargs)
    assert not est.ok and est.bound is not None and est.bound[0] == "above"
    _holds(est, obj.omega_n / math.pi, "coarse_to_fine on tilelink-v0 #37")


@pytest.mark.parametrize(("agent", "omega_pi"), [("coarse_to_fine", 10.0), ("bayes", 20.0), ("ppo", 5.0)])
def test_item1_objects_inside_the_range_keep_their_estimate(agent, omega_pi):
    """The test beyond the range does not refuse what the probes place inside it: in-range objects keep an
    estimate whose 95 % interval holds the truth (rates over atlas-v0: experiments/results/estimate_contract.md)."""
    est = _episode(agent, omega_pi, 0)
    assert est.ok, est.reason
    assert est.omega_n_ci95[0] <= omega_pi * math.pi <= est.omega_n_ci95[1]


def test_item1_the_extended_model_and_its_verdict():
    """The extension atlases lie outside the member's range and touch it; the extended model is made only where
    every member has one (the point mass and the rigid tiles; not the lab pool, not a disc of another mass); its
    grid continues the base grid; the incremental state gives the bound identify_atlas gives."""
    from plate_env.identify.forward import load_forward_model
    from plate_env.identify.identifiability import extended_model
    from plate_env.identify.inference import identify_atlas
    from plate_env.identify.posterior_state import PosteriorState
    from plate_env.surrogate.conditioning import KnownInputs

    fm = load_forward_model("tilelink/pointmass")
    wide = extended_model(fm)
    assert wide is not None and len(wide.members) == 3
    lo, hi = fm.identifiable_range
    w_lo, w_hi = wide.omega_range
    assert w_lo < 0.3 * math.pi and w_hi > 200 * math.pi
    assert [round(float(m.atlas.omega_n[k]) / math.pi, 3) for m, k in zip(wide.members[1:], (-1, 0), strict=True)] \
        == [round(lo / math.pi, 3), round(hi / math.pi, 3)]
    assert extended_model(load_forward_model("lab")) is None  # its PyBullet member has no extension
    rigid = load_forward_model("tilelink/rigid_fast")
    wide_rigid = extended_model(rigid)  # the faithful physics' extensions: same backend, time step and windows
    assert wide_rigid is not None and wide_rigid.members[:1] == rigid.members
    assert all(m.label == "tilelink/rigid_fast" and not (rigid.identifiable_range[0] < m.atlas.omega_n[0] <
                                                          rigid.identifiable_range[1]) for m in wide_rigid.members[1:])
    w_ext, _ = wide_rigid.grid(321, 16)  # the base grid continued at its step: the in-range nodes are the base's
    w_base, _ = rigid.grid(321, 16)
    k = int(np.searchsorted(w_ext, w_base[0]))
    assert np.array_equal(w_ext[k:k + w_base.size], w_base) and w_ext[0] < 2.5 * math.pi * 0.95
    assert extended_model(load_forward_model("tilelink/pointmass", KnownInputs(mass=0.03))) is None
    assert extended_model(load_forward_model("pybullet/pybullet")) is None
    # coarse_to_fine's 12 probes of a 60 pi object (seed 0): explained by 27.4 pi, and by objects above 45 pi
    rows = [(10.0, 12.07, False), (16.0, 104.46, False), (22.0, 439.79, False), (28.0, 634.32, False),
            (34.0, 0.0, True), (40.0, 0.0, True), (30.0, 657.2, False), (28.25, 641.99, False), (32.0, 0.0, True),
            (28.5, 0.0, True), (30.5, 0.0, True), (29.5, 662.59, False)]
    f, y, u = (np.array(c) for c in zip(*rows, strict=True))
    t = ProbeTable.from_arrays(f, np.full(f.size, 3.0), y, np.where(u, 0.0, 0.5), u.astype(bool))
    est = identify_atlas(t, fm)
    assert not est.ok and est.bound is not None and est.bound[0] == "above" and est.bound[1] < 60 * math.pi
    assert est.check.passed and 20 * math.pi < est.omega_n < 35 * math.pi  # the alias the check cannot refuse
    state = PosteriorState(fm)
    state.add_table(t)
    assert state.estimate().bound == est.bound and state.estimate().reason == est.reason


_OBJECTS = dict(log_omega=st.floats(math.log(0.3), math.log(200.0)), agent=st.sampled_from(AGENTS),
                seed=st.integers(0, 3))


@settings(max_examples=16, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow],
          phases=[Phase.explicit, Phase.generate])  # no shrinking: each example is an episode (~1 s)
@given(**_OBJECTS)
@example(log_omega=math.log(60.0), agent="coarse_to_fine", seed=0)  # the issue's
@example(log_omega=math.log(200.0), agent="ppo", seed=0)
def test_contract_property_every_agent_over_0p3_to_200pi(log_omega, agent, seed):
    """Property over objects 0.3-200 pi rad/s (log-uniform) on the live point mass, every shipped agent: outside
    1.4-45 pi no estimate, and a stated bound always on the truth's side (~15 s)."""
    omega_pi = math.exp(log_omega)
    _holds(_episode(agent, omega_pi, seed), omega_pi, f"{agent} seed {seed}")


@pytest.mark.slow
@settings(max_examples=120, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow],
          phases=[Phase.generate], database=None)
@given(**_OBJECTS)
def test_contract_property_every_agent_over_0p3_to_200pi_many(log_omega, agent, seed):
    """The property above on 120 objects (~2 min)."""
    omega_pi = math.exp(log_omega)
    _holds(_episode(agent, omega_pi, seed), omega_pi, f"{agent} seed {seed}")


def test_item1_the_verdict_reads_mass_outside_the_range_on_each_side():
    """outside_mass on made-up extended posteriors (range 10-100 rad/s): mass only inside -> no verdict; > EDGE_MASS
    above -> a bound above at the 2.5 % quantile; below -> below at the 97.5 %; both sides -> no bound."""
    from plate_env.identify.estimate import EDGE_MASS, Posterior
    from plate_env.identify.identifiability import outside_mass

    w, a = np.geomspace(1.0, 1000.0, 61), np.linspace(0.5, 1.1, 5)

    def verdict(masses):
        p = np.full(w.size, 1e-12)
        for x, m in masses:
            p[np.argmin(abs(w - x))] += m
        return outside_mass(Posterior(w, a, np.outer(p / p.sum(), np.ones(5) / 5), identifiable_range=(1.0, 1000.0)),
                            (10.0, 100.0))

    assert verdict([(30.0, 1.0)]).side is None
    v = verdict([(30.0, 1 - 2 * EDGE_MASS), (300.0, 2 * EDGE_MASS)])
    assert v.side == "above" and v.bound[0] == "above" and v.bound[1] < 31.0 and v.above > EDGE_MASS
    assert verdict([(30.0, 1 - 2 * EDGE_MASS), (3.0, 2 * EDGE_MASS)]).bound[0] == "below"
    both = verdict([(30.0, 0.5), (3.0, 0.25), (300.0, 0.25)])
    assert both.side == "both" and both.bound is None and "no bound" in both.reason(30.0, "m")
    assert verdict([(30.0, 1 - EDGE_MASS / 2), (300.0, EDGE_MASS / 2)]).side is None


# ------------------------------------------------------------------ every method on sweeps beyond the range
def _live_sweeps(omega_pis, alpha_deg: float = 45.0, seed: int = 0, model: str = "pointmass") -> list[ProbeTable]:
    """Live tile-link sweeps (16 probes, 10-40 Hz, 3 deg) of 13.6 g discs at ``omega_pis`` (pi rad/s), placed."""
    from plate_env.build.eval_sets import placed_sweeps
    from plate_env.core.objects import ObjectSpec
    from plate_env.physics import make_physics

    objs = [ObjectSpec(omega_n=w * math.pi, alpha=math.radians(alpha_deg)) for w in omega_pis]
    physics = make_physics("tilelink", model=model)
    try:
        res = physics.run(placed_sweeps(objs, F_HZ, 3.0, np.random.default_rng(seed)))
    finally:
        physics.close()
    return [ProbeTable.from_results(res[i * F_HZ.size:(i + 1) * F_HZ.size]) for i in range(len(objs))]


@pytest.mark.parametrize("which", ["atlas tilelink/pointmass", "lorentz tilelink/pointmass"])
def test_item1_every_method_on_the_point_mass_gives_no_estimate_beyond_the_range(which):
    """Live point-mass sweeps of 0.3, 100 and 200 pi objects read by the methods that know the physics: no
    estimate, and a bound only on the truth's side."""
    omegas = (0.3, 100.0, 200.0)
    for w, t in zip(omegas, _live_sweeps(omegas), strict=True):
        _holds(_fit(which, t), w, f"{which} at {w} pi")


def test_item1_the_faithful_physics_beyond_its_range_gets_no_estimate():
    """Live rigid-tile sweeps (rigid_fast, the faithful physics) of 0.3 and 1 pi objects, below its atlas's 2.5 pi,
    and of a 100 pi one, above its 45 pi: its own model read them as 3.2, 4.2 and 29.8 pi (experiments/results/
    estimate_contract.md, section 4) before its extensions; now no estimate, a bound only on the truth's side. In
    range (10 pi) it answers."""
    from plate_env.identify.estimators import make_estimator

    fit = make_estimator("atlas", "tilelink/rigid_fast").fit
    for w, a in ((0.3, 35.0), (1.0, 45.0), (100.0, 35.0)):
        (t,) = _live_sweeps([w], a, 0, model="rigid_fast")
        est = fit(t)
        assert not est.ok, f"{w} pi read as {est.omega_n / math.pi:.3g} pi"
        _holds(est, w, f"rigid tiles at {w} pi")
    (t,) = _live_sweeps([10.0], 45.0, 0, model="rigid_fast")
    assert fit(t).ok


def _cached_sweeps(physics: str):
    """The out-of-range study's live sweeps (experiments/out_of_range_methods.py; committed cache): (omega_n pi,
    alpha deg, ProbeTable)."""
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "experiments" / "cache" / "out_of_range_sweeps.jsonl"
    out = []
    for line in path.read_text().splitlines():
        d = json.loads(line)
        if d["physics"] == physics:
            cols = list(zip(*d["probes"], strict=True))
            out.append((d["omega_pi"], d["alpha_deg"], ProbeTable.from_arrays(
                *[np.array(c, dtype=bool if i == 4 else float) for i, c in enumerate(cols)])))
    return out


@pytest.mark.parametrize("which", ["calibrated paper", "lorentz lab", "lorentz paper", "atlas lab"])
def test_item1_readings_of_unknown_origin_of_point_mass_discs_beyond_the_range(which):
    """The study's 24 point-mass sweeps at 0.3-1.2 and 50-200 pi read through the paper's calibration, the lab's
    and the paper's Eq. (10) lines and the ``lab`` pool (readings of data whose physics is unknown): at 2247dd9 the
    calibration read 12 of them (10 excluding the truth), each line set 3, the pool 14; now none, because every
    shipped physics that explains their probes places the disc beyond its range
    (plate_env.identify.unknown_origin.verdict). Inside the range (3, 10, 30 pi) the calibration and the pool still
    read 8 of 9."""
    inside = 0
    for w, a, t in _cached_sweeps("pointmass"):
        est = _fit(which, t)
        _holds(est, w, f"{which} at {w} pi, alpha {a} deg")
        inside += RANGE_PI[0] <= w <= RANGE_PI[1] and est.ok
    assert inside >= (8 if which in ("calibrated paper", "atlas lab") else 3)


def test_item1_the_lab_pool_on_rigid_discs_beyond_the_range_answers_only_with_the_truth_inside():
    """The study's 24 rigid-tile sweeps beyond the range through the ``lab`` pool: 20 estimates before the pool's
    readings went through every physics' statement, now at most 9 (the discs at 0.3-1.2 pi that the point mass
    explains inside its range), each 95 % interval holding the truth."""
    n = 0
    for w, a, t in _cached_sweeps("rigid_fast"):
        if RANGE_PI[0] <= w <= RANGE_PI[1]:
            continue
        est = _fit("atlas lab", t)
        n += est.ok
        assert not est.ok or est.omega_n_ci95[0] <= w * math.pi <= est.omega_n_ci95[1], f"{w} pi, alpha {a}"
    assert n <= 9


def _eval_discs(family: str, omegas_pi: tuple[float, ...]):
    """Discs of an in-range evaluation set (plate_env.build.eq10.LAB_SETS; committed sweep caches) at the given
    omega_n (pi rad/s, to 2 decimals): (omega_n pi, ProbeTable)."""
    from pathlib import Path

    from plate_env.build.eq10 import LAB_SETS, lab_backend_of
    from plate_env.build.eval_sets import run_eval_set

    es = LAB_SETS[family]
    cache = Path(__file__).resolve().parents[1] / "experiments" / "cache"
    tables = run_eval_set(es, lab_backend_of(family), None, cache_dir=cache)[es.a_p_deg[0]]
    got = [(round(o.omega_n / math.pi, 2), t) for o, t in zip(es.objects(), tables, strict=True)]
    return [(w, t) for w, t in got if w in omegas_pi]


def test_item1_point_mass_discs_of_other_joint_values_in_range_keep_their_reading():
    """In-range point-mass discs, each with its own joint/contact values (the lab family's evaluation set), that the
    default point mass cannot explain (its check fails) and the rigid tiles place beyond their range: when the point
    mass was asked with its default values alone (a060cb7), every explaining physics placed them beyond: the paper's
    calibration refused 30 of its 116 readings of the set, the pool would have refused 26 of 104
    (experiments/results/estimate_contract.md, section 5).
    The point mass is now asked with every joint value the pool gives it, each extended beyond the range
    (plate_env.identify.unknown_origin.family_model), and reads them inside."""
    discs = _eval_discs("pointmass", (3.7, 7.71, 11.09, 17.55, 29.07))
    assert len(discs) == 5
    for w, t in discs:  # at a060cb7 the paper's calibration refused all five ("every shipped physics ... beyond")
        for which in ("calibrated paper", "atlas lab"):
            est = _fit(which, t)
            assert est.ok, f"{which}, {w} pi: {est.reason}"
    from plate_env.identify.unknown_origin import physics_readings
    from plate_env.surrogate.conditioning import KnownInputs

    for w, t in discs:
        kinds = {r.name: r.kind for r in physics_readings(t, KnownInputs())}
        assert kinds["tilelink/pointmass"] == "inside", (w, kinds)


def test_item1_an_estimate_says_beyond_which_end_it_places_the_object():
    """``Estimate.beyond`` (what the unknown-origin rule reads, rather than its reason's words): on the study's
    point-mass sweeps its own model names the side of 22 of the 24 out-of-range objects, always the truth's, equal to
    the bound's side; none inside the range."""
    n = 0
    for w, a, t in _cached_sweeps("pointmass"):
        est = _fit("atlas tilelink/pointmass", t)
        inside = RANGE_PI[0] <= w <= RANGE_PI[1]
        if est.beyond is not None:
            assert not inside and est.beyond == ("below" if w < RANGE_PI[0] else "above"), (w, a, est.beyond)
            n += 1
        assert est.bound is None or est.bound[0] == est.beyond
    assert n >= 20


def test_item1_the_lab_pools_episode_estimates_go_through_the_rule_as_its_fits_do():
    """An episode reads the lab pool probe by probe (its incremental posterior, each physics' statement kept and fed
    the new probes: plate_env.identify.unknown_origin.ReadingsState); after every probe its estimate is the one a
    fit of the probes so far gives, the rule included: a 200 pi point-mass sweep, which the pool alone reads
    (27 pi before the rule), ends as no estimate either way."""
    from plate_env.env.episode import estimator_prefixes
    from plate_env.identify.estimators import make_estimator
    from plate_env.identify.unknown_origin import ReadingsState, physics_readings
    from plate_env.surrogate.conditioning import KnownInputs

    (far,) = [t for w, a, t in _cached_sweeps("pointmass") if (w, a) == (200.0, 45.0)]
    est = make_estimator("atlas", "tilelink/pointmass", forward="lab")
    steps = estimator_prefixes(est, far)
    for k in (3, 8, len(far)):
        prefix = far.subset(np.arange(len(far)) < k)
        fit = est.fit(prefix)
        assert (steps[k - 1].ok, steps[k - 1].reason, steps[k - 1].omega_n) == (fit.ok, fit.reason, fit.omega_n), k
    assert not steps[-1].ok and "every shipped physics" in steps[-1].reason
    state = ReadingsState(KnownInputs())
    for k in (5, len(far), 4):  # grows, then a table that is not its extension starts over
        prefix = far.subset(np.arange(len(far)) < k)
        assert state.readings(prefix) == physics_readings(prefix, KnownInputs()), k


def test_item1_a_reading_of_unknown_origin_stands_where_some_physics_explains_it_in_range(monkeypatch):
    """The rule asks every shipped physics, and one answering inside its range lets the reading stand: a live
    rigid-tile sweep at 10 pi through the paper's calibration answers; the study's 200 pi point-mass sweep is placed
    beyond by every physics that explains it, and by none when only the sheet (not extended) is asked."""
    import plate_env.identify.unknown_origin as idf
    from plate_env.surrogate.conditioning import KnownInputs

    (rigid,) = _live_sweeps([10.0], 45.0, 0, model="rigid_fast")
    assert _fit("calibrated paper", rigid).ok and idf.verdict(rigid, KnownInputs()) is None
    (far,) = [t for w, a, t in _cached_sweeps("pointmass") if (w, a) == (200.0, 35.0)]
    assert idf.verdict(far, KnownInputs()) is not None
    monkeypatch.setattr(idf, "PHYSICS_MODELS", ("pybullet/pybullet",))
    assert idf.verdict(far, KnownInputs()) is None


def test_item1_what_the_unknown_origin_rule_cannot_resolve():
    """The premise of the open gap below: a live 100 pi point-mass sweep that the point mass (with every joint value,
    extended) places beyond its range with a true bound, and the rigid tiles explain inside theirs (check passed,
    95 % interval far below the truth): data that two shipped physics explain on opposite sides of the range."""
    from plate_env.identify.unknown_origin import physics_readings
    from plate_env.surrogate.conditioning import KnownInputs

    t = _live_sweeps((0.3, 100.0, 200.0))[1]  # the xfail's sweep (placements drawn for the three discs)
    r = {x.name: x for x in physics_readings(t, KnownInputs())}
    pm, rigid = r["tilelink/pointmass"], r["tilelink/rigid_fast"]
    assert pm.kind == "beyond" and pm.bound is not None and pm.bound[0] == "above" and pm.bound[1] < 100 * math.pi
    assert rigid.kind == "inside" and rigid.p_value is not None and rigid.p_value > 0.1
    assert rigid.ci95 is not None and rigid.ci95[1] < 45 * math.pi


@pytest.mark.xfail(strict=True, reason="issue 37, its blocked part (not identifiable from the data): a disc beyond "
                   "the range that another shipped physics explains inside its range is read by every reading of "
                   "unknown origin (the live 100 pi point-mass sweep: "
                   "the rigid tiles read it as 7.6 pi, p 0.85); the rule that refuses as soon as some physics places "
                   "a disc beyond keeps 27 of 104 in-range point-mass discs, 8 of them with a false bound "
                   "(experiments/results/estimate_contract.md, section 5)")
def test_item1_readings_of_unknown_origin_give_no_estimate_beyond_the_range():
    omegas = (0.3, 100.0, 200.0)
    for w, t in zip(omegas, _live_sweeps(omegas), strict=True):
        for which in ("calibrated paper", "lorentz lab", "lorentz paper", "atlas lab"):
            _holds(_fit(which, t), w, f"{which} at {w} pi")


@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow],
          phases=[Phase.explicit, Phase.generate])  # no shrinking: each example is a live sweep and its fits
@given(log_omega=st.floats(math.log(0.3), math.log(200.0)), alpha_deg=st.floats(30.0, 60.0),
       seed=st.integers(0, 2 ** 16))
@example(log_omega=math.log(100.0), alpha_deg=45.0, seed=0)
def test_contract_property_every_method_of_the_physics_over_0p3_to_200pi(log_omega, alpha_deg, seed):
    """Property over live point-mass sweeps of objects 0.3-200 pi rad/s (log-uniform), alpha 30-60 deg, read by
    every estimator that knows the physics (the atlas and the Lorentz method on the point mass): outside 1.4-45 pi
    no estimate, and a stated bound always on the truth's side."""
    omega_pi = math.exp(log_omega)
    (t,) = _live_sweeps([omega_pi], alpha_deg, seed)
    for which in ("atlas tilelink/pointmass", "lorentz tilelink/pointmass"):
        _holds(_fit(which, t), omega_pi, f"{which}, alpha {alpha_deg:.1f} deg, seed {seed}")


def test_a_calibrated_predictive_beyond_its_grid_is_no_estimate_not_a_clamped_number():
    """The calibrated map's predictive was read on 1-400 rad/s; a 100 pi point-mass sweep through the paper's
    calibration put most of it below 1 rad/s and read omega_n = 1.00 rad/s, 68 % [1.00, 1.13] (quantiles clamped at
    the grid's end, experiments/results/out_of_range_methods.json). The grid is now 0.01-1e5 rad/s, and no estimate is
    read when more than the 95 % interval's tail lies beyond it, naming the mass beyond."""
    from plate_env.identify.adaptive_calibration import LOG_OMEGA_GRID, TAIL, mixed_prediction

    g = LOG_OMEGA_GRID

    def cdf(mu: float, sd: float) -> np.ndarray:
        from scipy.special import ndtr

        return ndtr((g - mu) / sd)

    assert mixed_prediction(cdf(math.log(30.0), 0.3), None, 1.0).ok  # well inside: read
    low = mixed_prediction(cdf(g[0] - 1.0, 0.5), None, 1.0)
    assert not low.ok and "below 0.01 rad/s" in low.reason
    high = mixed_prediction(None, cdf(g[-1] + 1.0, 0.3), 0.0)
    assert not high.ok and "above 1e+05 rad/s" in high.reason
    edge = cdf(g[0] + 2.1 * 0.5, 0.5)  # 1.8 % below the grid: still read, its 95 % interval inside it
    assert edge[0] < TAIL and mixed_prediction(edge, None, 1.0).ci95[0] > math.exp(g[0])
    assert not mixed_prediction(cdf(g[0] + 1.8 * 0.5, 0.5), None, 1.0).ok  # 3.6 % below: its 2.5 % quantile unread
    (t,) = _live_sweeps([100.0], 45.0, 0)
    est = _fit("calibrated paper", t)
    assert not est.ok or est.omega_n_ci95[0] > math.exp(g[0]) * (1 + 1e-9), "a clamped calibrated reading"


def test_a_calibrated_reading_outside_the_members_range_is_no_estimate_and_no_bound(monkeypatch):
    """A calibrated median outside the range the calibration's members identify (the lab pool's 1.4-45 pi) is no
    estimate and no bound (the disc's physics may not be the references': the predictive's tail is no promise)."""
    import plate_env.identify.lab_calibration_file as lcf
    from plate_env.identify.lab_calibration import Prediction

    (t,) = _live_sweeps([10.0], 45.0, 0)
    assert _fit("calibrated paper", t).ok
    for w_pi in (0.5, 80.0):
        w = w_pi * math.pi
        monkeypatch.setattr(lcf, "predict_adaptive", lambda *a, w=w: Prediction(True, w, (0.8 * w, 1.2 * w),
                                                                                (0.6 * w, 1.5 * w)))
        est = _fit("calibrated paper", t)
        assert not est.ok and est.bound is None and "outside the range 'lab' identifies" in est.reason, est.reason
