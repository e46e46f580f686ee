"""An outer TimeLimit shorter than the episode (issue 38 item 5): what truncation means for the reward, as the env's
docstring ('Episode End') says: the error is never charged; the estimate of the probes so far is what a stop
would have charged."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import plate_env  # noqa: F401 - registers the ids
from plate_env.env.rotation import PlateRotationEnv

#: Six probes across the band: enough that the estimate so far stands (four were, until the estimate contract of
#: issue 37 made the estimate of probes that cannot place the object inside the identifiable range a bound).
ACTIONS = [np.array([f, 1.0, 0.5, -1.0], dtype=np.float32) for f in (-0.8, -0.5, -0.2, 0.1, 0.4, 0.7)]
STOP = np.array([0.0, 0.0, 0.0, 1.0], dtype=np.float32)


def _play(env, actions, seed=5):
    env.reset(seed=seed)
    rewards, last = [], None
    for a in actions:
        _, r, terminated, truncated, info = env.step(a)
        rewards.append(r)
        last = (terminated, truncated, info)
        if terminated or truncated:
            break
    return rewards, last


def test_a_truncated_episode_pays_probe_costs_only_and_a_stop_charges_the_estimate_so_far():
    cut = gym.make("PlateRotationAtlas-v0", max_episode_steps=len(ACTIONS))
    rewards, (terminated, truncated, info) = _play(cut, ACTIONS)
    assert truncated and not terminated and len(rewards) == len(ACTIONS)
    e = cut.unwrapped
    cost = e.cost_per_sim_s * info["sim_s"]
    assert np.isclose(sum(rewards), -cost, rtol=1e-9, atol=1e-12)  # the probe costs, and nothing else
    assert not info["estimate"]["ok"] and not info["truth_revealed"]  # a non-final step's info
    so_far = e.estimate()
    assert so_far.ok
    error = so_far.relative_error(e.hidden_object().omega_n)
    assert error > 0.0
    # the same object, the same probes, then a stop: terminated, and the error of that estimate is charged
    full = gym.make("PlateRotationAtlas-v0")
    rewards2, (terminated2, truncated2, info2) = _play(full, [*ACTIONS, STOP])
    assert terminated2 and not truncated2 and np.allclose(rewards2[:len(ACTIONS)], rewards)
    assert np.isclose(rewards2[-1], -min(error, full.unwrapped.error_cap))
    assert np.isclose(info2["relative_error"], error)


def test_the_docstring_says_what_truncation_means():
    doc = PlateRotationEnv.__doc__.split("## Episode End")[1].split("## Info")[0]
    for needle in ("TimeLimit", "the error is never charged", "env.unwrapped.estimate()", "max_probes"):
        assert needle in doc, needle
