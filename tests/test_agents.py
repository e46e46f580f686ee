"""Probing agents: each runs end to end; bayes narrows its posterior around the truth (identify: test_cli.py)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import plate_env  # noqa: F401
from agents import make_agent
from agents.runner import run_episode
from plate_env.atlas import atlas_from_repeats
from plate_env.fitting import lorentzian

AGENTS = [("grid", dict(n=6)), ("coarse_to_fine", dict(n_coarse=4, n_fine=2)), ("bayes", dict(target_rel=0.1))]


@pytest.mark.parametrize("physics", ["atlas", "tilelink"])
@pytest.mark.parametrize("name, kw", AGENTS)
def test_agent_runs_an_episode_end_to_end(physics, name, kw):
    env = gym.make("PlateRotation-v0", physics=physics, max_probes=8)
    res = run_episode(env, make_agent(name, **kw), seed=1, options={"omega_n": 12 * math.pi, "alpha": 0.7})
    assert 1 <= res.n_probes <= 8 and res.sim_s > 0
    assert res.estimate.ok or res.estimate.reason
    if res.estimate.ok:
        assert math.isfinite(res.estimate.omega_n) and res.estimate.omega_n > 0
    env.close()


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
    agent = make_agent("bayes", atlas=atlas, target_rel=0.0)
    truth = 14 * math.pi
    widths = []
    e = env.unwrapped
    obs, _ = env.reset(seed=3, options={"omega_n": truth, "alpha": math.radians(45)})
    from agents.base import ProbeContext

    agent.reset(ProbeContext.from_env(env), np.random.default_rng(3))
    for _ in range(8):
        probe = agent.next_probe(e.table(), obs)
        obs, *_ = env.step(e.encode_action(probe.f_p_hz, probe.a_p_deg, probe.measure_s))
        agent._update(e.table())
        widths.append(agent.relative_std())
    assert widths[-1] < 0.5 * widths[0]
    post = agent.posterior().sum(1)
    cdf = np.cumsum(post) / post.sum()
    lo, hi = np.interp([0.025, 0.975], cdf, agent.omega)
    assert lo <= truth <= hi
