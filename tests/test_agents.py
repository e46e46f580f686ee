"""Probing agents: each runs end to end; bayes narrows its posterior around the truth (identify: test_cli.py)."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import plate_env  # noqa: F401
from plate_env.env.episode import run_episode
from plate_env.identify.fitting import lorentzian
from plate_env.surrogate.atlas import atlas_from_repeats
from plate_env_agents import make_agent

TRUTH = {"omega_n": 12 * math.pi, "alpha": 0.7}


def _episode(physics: str, name: str, **kw):
    env = gym.make("PlateRotation-v0", physics=physics, max_probes=8)
    try:
        return run_episode(env, make_agent(name, **kw), seed=1, options=TRUTH)
    finally:
        env.close()


@pytest.mark.parametrize("physics", ["atlas", "tilelink"])
def test_grid_agent_runs_the_papers_sweep_and_says_why_six_probes_cannot_be_fitted(physics):
    res = _episode(physics, "grid", n=6)
    assert res.probes.f_p_hz.tolist() == pytest.approx(np.linspace(10.0, 40.0, 6).tolist())
    assert res.probes.amplitudes() == [3.0]
    assert 0 < res.sim_s <= 6 * (0.2 + 0.5 + 1.0) + 1e-9  # ramp + settle + 1 s window each, less if unstable
    # 6 Hz spacing leaves one probe in the first hump's window: the paper's method gives no estimate, and says so
    assert res.estimate.method == "lorentz" and not res.estimate.ok
    assert "usable probes in the fit window" in res.estimate.reason


@pytest.mark.parametrize("physics", ["atlas", "tilelink"])
def test_coarse_to_fine_refines_next_to_the_coarse_peak(physics):
    res = _episode(physics, "coarse_to_fine", n_coarse=4, n_fine=2)
    f = res.probes.f_p_hz
    assert len(f) == 6 and f[:4].tolist() == pytest.approx([10.0, 20.0, 30.0, 40.0])
    stable = ~res.probes.unstable[:4]
    peak = f[:4][stable][np.argmax(res.probes.omega_b_deg_s[:4][stable])]
    assert all(0 < abs(x - peak) <= 4.0 for x in f[4:])  # within the first +-width_hz round around the peak
    est = res.estimate
    assert est.ok and est.method == "atlas" and est.omega_n_ci95[0] <= TRUTH["omega_n"] <= est.omega_n_ci95[1]


@pytest.mark.parametrize("physics", ["atlas", "tilelink"])
def test_bayes_stops_at_its_target_with_the_truth_inside_its_interval(physics):
    res = _episode(physics, "bayes", target_rel=0.1)
    est = res.estimate
    assert est.ok and est.method == "atlas"
    assert 3 <= res.n_probes < 8  # stopped by its target, before the budget (min_probes 3)
    assert est.omega_n_stderr / est.omega_n <= 0.1
    assert est.omega_n_ci95[0] <= TRUTH["omega_n"] <= est.omega_n_ci95[1]
    assert len(set(zip(res.probes.f_p_hz.tolist(), res.probes.a_p_deg.tolist(), strict=True))) == res.n_probes


def _lorentz_atlas():
    """An atlas whose response is an exact Lorentzian with f0 rising with log omega_n (no instability)."""
    f = np.arange(10.0, 41.0, 1.0)
    w = np.geomspace(3, 40, 12) * math.pi
    a = np.radians([30.0, 40.0, 50.0, 60.0])
    ff, ww, _ = np.meshgrid(f, w, a, indexing="ij")
    mean = lorentzian(ff, 600.0, 20.0 + 4.0 * np.log(ww / (3 * math.pi)), 5.0)
    reps = np.repeat(mean[:, None, :, :, None], 2, axis=-1)
    return atlas_from_repeats("toy", "toy", f, [3.0], w, a, reps, np.full(reps.shape, 5.0),
                              np.zeros(reps.shape, bool), {})


def test_bayes_posterior_narrows_and_contains_truth_on_synthetic_lorentzian_data():
    atlas = _lorentz_atlas()
    env = gym.make("PlateRotation-v0", physics="atlas", physics_options={"atlas": atlas, "source": "toy",
                                                                        "model": "toy"},
                   amplitudes_deg=(3.0,), max_probes=10)
    from plate_env.identify.forward import ForwardModel, Member

    agent = make_agent("bayes", forward=ForwardModel("toy", (Member(atlas, 5.0),)), target_rel=0.0)
    truth = 14 * math.pi
    widths = []
    e = env.unwrapped
    obs, _ = env.reset(seed=3, options={"omega_n": truth, "alpha": math.radians(45)})
    from plate_env.env.protocol import ProbeContext

    agent.reset(ProbeContext.from_env(env), np.random.default_rng(3))
    widths.append(agent.relative_std())  # the prior's: log-uniform over the atlas's 2pi-40pi
    for _ in range(8):
        probe = agent.next_probe(e.table(), obs)
        obs, *_ = env.step(e.encode_action(probe.f_p_hz, probe.a_p_deg, probe.measure_s))
        agent._update(e.table())
        widths.append(agent.relative_std())
    assert widths[0] > 0.5 and widths[-1] < 0.1 * widths[0]
    assert all(b <= a * 1.05 for a, b in zip(widths[1:], widths[2:], strict=False))  # it keeps narrowing
    lo, hi = agent.posterior().omega().ci95
    assert lo <= truth <= hi


def test_bayes_estimate_uses_its_design_discrepancy_and_stops_on_what_the_probes_say():
    """On a forward model with a coherent discrepancy and an offset between models (a grid padded beyond the
    atlas), bayes still reaches its target (the stopping rule reads the probes' information, not the discrepancy
    no probe can reduce), and the episode's estimate comes from its design model: its blur, the discrepancy
    calibrated for this forward model (DESIGN_DISCREPANCY, or one given) in place of the model's own, the offset
    between models kept."""
    from plate_env.identify.forward import ForwardModel, Member
    from plate_env.identify.inference import identify_atlas
    from plate_env_agents.bayes import DESIGN_DISCREPANCY

    atlas = _lorentz_atlas()
    env = gym.make("PlateRotation-v0", physics="atlas", physics_options={"atlas": atlas, "source": "toy",
                                                                        "model": "toy"},
                   amplitudes_deg=(3.0,), max_probes=12)
    fm = ForwardModel("toy", (Member(atlas, 5.0),), sigma_eps=0.1, offset_sigma=0.1, offset_nu=2.0)
    agent = make_agent("bayes", forward=fm, target_rel=0.05, design_discrepancy=(0.2, 3.0))
    try:
        res = run_episode(env, agent, seed=4, options={"omega_n": 14 * math.pi, "alpha": math.radians(45)})
    finally:
        env.close()
    assert res.n_probes < 12 and res.estimate.ok  # stopped by its target although sigma_eps, offset 0.1 > 0.05
    model = agent.estimate_model()
    assert (model.sigma_eps, model.eps_nu) == (0.2, 3.0)  # the given design discrepancy replaces the model's
    assert (model.offset_sigma, model.offset_nu) == (0.1, 2.0)  # the offset between models is kept as it is
    assert model.members[0].blur == pytest.approx(agent.blur)
    assert res.estimate.forward == model.name
    # without one given: the calibrated one for a forward model named in DESIGN_DISCREPANCY, else the model's own
    own = make_agent("bayes", forward=fm)
    own.fm = fm
    assert own.design_eps() == (0.1, math.inf)
    named = dataclasses.replace(fm, name="tilelink/pointmass")
    own.fm = named
    assert own.design_eps() == DESIGN_DISCREPANCY["tilelink/pointmass"] != (named.sigma_eps, named.eps_nu)
    with pytest.raises(ValueError, match="design_discrepancy nu"):
        make_agent("bayes", design_discrepancy=(0.01, 0.1))
    plain = identify_atlas(res.probes, fm)
    assert res.estimate.omega_n_ci95[1] / res.estimate.omega_n_ci95[0] > plain.omega_n_ci95[1] / plain.omega_n_ci95[0]
