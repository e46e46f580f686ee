"""One estimator object per method (issue 35): the registry, equality, and that the env, the episode loop and
identify() all go through it (the same estimate, bit for bit, as the method's own function)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify
from plate_env.identify.estimators import (
    AtlasEstimator,
    CalibratedEstimator,
    Estimator,
    ForwardName,
    LorentzEstimator,
    agent_estimator,
    fit_or_refuse,
    make_estimator,
)
from plate_env.identify.fitting import lorentzian
from plate_env.surrogate.conditioning import KnownInputs

F_HZ = np.arange(10.0, 41.0, 2.0)


def _table() -> ProbeTable:
    values = np.where(F_HZ > 34, 0.0, lorentzian(F_HZ, 600.0, 31.0, 6.0))
    return ProbeTable.from_arrays(F_HZ, np.full(F_HZ.size, 3.0), values, np.full(F_HZ.size, 2.0), values == 0.0)


def test_forward_name_is_parsed_once_and_written_back():
    name = ForwardName.parse("tilelink/pointmass")
    assert (name.physics, name.model, str(name)) == ("tilelink", "pointmass", "tilelink/pointmass")
    for bad in ("lab", "/pointmass", "tilelink/", ""):
        with pytest.raises(ValueError, match="physics/model|non-empty"):
            ForwardName.parse(bad)


def test_the_registry_makes_one_estimator_per_method_and_refuses_what_it_does_not_read():
    known = KnownInputs()
    atlas = make_estimator("atlas", "tilelink/pointmass", known)
    assert isinstance(atlas, AtlasEstimator) and isinstance(atlas, Estimator) and atlas.method == "atlas"
    assert atlas == AtlasEstimator(ForwardName("tilelink", "pointmass"), known) == AtlasEstimator("tilelink/pointmass")
    assert atlas != make_estimator("atlas", "tilelink/pointmass", known, forward="lab")
    lorentz = make_estimator("lorentz", ForwardName("paper", "pointmass"))
    assert isinstance(lorentz, LorentzEstimator) and lorentz.start() is None
    assert isinstance(make_estimator(calibration="paper"), CalibratedEstimator)
    with pytest.raises(ValueError, match="unknown identification method 'bayes'"):
        make_estimator("bayes")
    with pytest.raises(ValueError, match="give no method, forward or options"):
        make_estimator("lorentz", calibration="paper")
    with pytest.raises(TypeError, match="takes no options"):
        make_estimator("atlas", calibrations={})


@pytest.mark.parametrize("method", ["atlas", "lorentz"])
def test_identify_is_its_estimators_fit(method):
    table = _table()
    a = identify(table, method=method, physics="tilelink", model="pointmass")
    b = make_estimator(method, "tilelink/pointmass").fit(table)
    assert a.to_dict() == b.to_dict() and (a.ok or a.check is not None)  # lorentz reads it, atlas refuses by its check


def test_an_incremental_start_gives_the_fit_bit_for_bit():
    table = _table()
    est = make_estimator("atlas", "tilelink/pointmass")
    state = est.start()
    state.add_table(table)
    assert state.estimate().to_dict() == est.fit(table).to_dict()


def test_fit_or_refuse_names_why():
    empty = ProbeTable.from_arrays([], [], [])
    assert fit_or_refuse(make_estimator("lorentz", "tilelink/pointmass"), empty).reason == "no probes"
    refused = fit_or_refuse(make_estimator("atlas", "paper/pointmass"), _table())
    assert not refused.ok and refused.method == "atlas" and "no forward model 'paper/pointmass'" in refused.reason


def test_an_agents_estimator_its_own_model_else_the_envs_else_its_methods():
    known = KnownInputs()
    name = ForwardName("tilelink", "pointmass")
    env_est = make_estimator("atlas", name, known)
    assert agent_estimator("atlas", None, "atlas", env_est, name, known) is env_est
    assert isinstance(agent_estimator("lorentz", None, "atlas", env_est, name, known), LorentzEstimator)
    own = env_est.forward_model()
    mine = agent_estimator("atlas", own, "atlas", env_est, name, known)
    assert mine.model is own and mine != env_est  # an agent's own model object: never mistaken for the env's


def test_the_env_and_the_episode_read_through_estimators():
    from plate_env.env import PlateRotationEnv
    from plate_env.env.episode import estimator_of, run_episode
    from plate_env_agents import make_agent

    env = PlateRotationEnv(physics="atlas")
    res = run_episode(env, make_agent("grid", n=8), seed=3)
    assert isinstance(estimator_of(env, make_agent("grid")), LorentzEstimator)
    assert isinstance(env.estimator(), AtlasEstimator) and env.posterior_state() is not None
    assert res.estimate.to_dict() == fit_or_refuse(LorentzEstimator(ForwardName("tilelink", "pointmass")),
                                                   res.probes).to_dict()
    lorentz_env = PlateRotationEnv(physics="atlas", method="lorentz")
    lorentz_env.reset(seed=3, options={"omega_n": 20 * math.pi})
    assert lorentz_env.posterior_state() is None  # the Lorentz method refits from scratch
