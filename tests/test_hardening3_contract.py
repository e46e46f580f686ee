"""Issue 37: one estimate contract for every method (uncalibrated, calibrated, Lorentz) and agent: data the model
cannot explain and objects outside the identifiable range get no estimate or a stated bound
(plate_env.identify.estimators: gated, gated_unknown_origin). Each item test fails before its fix."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify
from plate_env.identify.estimators import ForwardName, LorentzEstimator, make_estimator

F_HZ = np.arange(10.0, 41.0, 2.0)


def _table(values, se: float = 2.0) -> ProbeTable:
    """A 3-deg sweep of ``values`` (deg/s), every probe stable (zeros measured, as a CSV of zeros says)."""
    v = np.asarray(values, dtype=float)
    return ProbeTable.from_arrays(F_HZ, np.full(F_HZ.size, 3.0), v, np.full(F_HZ.size, se), np.zeros(F_HZ.size, bool))


#: Every estimator a user or an agent can reach on 3-deg data of unknown origin or of the point mass.
ESTIMATORS = {"atlas lab": dict(method="atlas", name="tilelink/pointmass", forward="lab"),
              "atlas tilelink/pointmass": dict(method="atlas", name="tilelink/pointmass"),
              "lorentz paper": dict(method="lorentz", name="paper/pointmass"),
              "lorentz lab": dict(method="lorentz", name="lab/lab"),
              "lorentz tilelink/pointmass": dict(method="lorentz", name="tilelink/pointmass"),
              "calibrated paper": dict(calibration="paper")}


def _fit(which: str, table: ProbeTable):
    return make_estimator(**ESTIMATORS[which]).fit(table)


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
    est = LorentzEstimator(ForwardName("paper", "pointmass")).fit(_table(np.zeros(F_HZ.size)))
    assert not est.ok


# ------------------------------------------------------------------------------------------------ live physics
#: The tilelink/pointmass atlas's identifiable range (pi rad/s): outside it the contract asks for no estimate or a
#: bound.
RANGE_PI = (1.4, 45.0)


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="issue 37 item 1 open: coarse_to_fine at 60 pi answers 27.4 pi, p 0.09 "
                   "(the check runs and passes: an in-range alias explains its 3-deg probes); ppo at 200 pi 1.65 pi")
@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow],
          phases=[Phase.explicit, Phase.generate])
@given(omega_pi=st.one_of(st.floats(0.3, 1.3), st.floats(50.0, 200.0)),
       agent=st.sampled_from(["grid", "coarse_to_fine", "bayes", "ppo"]), seed=st.integers(0, 3))
def test_contract_property_objects_outside_the_range_get_no_estimate_or_a_bound(omega_pi, agent, seed):
    """Property over objects 0.3-1.3 pi and 50-200 pi rad/s on the live point mass, every shipped agent."""
    import gymnasium as gym

    from plate_env.env.episode import run_episode
    from plate_env_agents import make_agent

    env = gym.make("PlateRotation-v0", physics="tilelink")
    try:
        res = run_episode(env, make_agent(agent), seed=seed, options={"omega_n": omega_pi * math.pi,
                                                                      "alpha": math.radians(45.0)})
    finally:
        env.close()
    est = res.estimate
    assert not est.ok, f"{agent} read {omega_pi:.3g} pi as {est.omega_n / math.pi:.3g} pi (seed {seed})"
