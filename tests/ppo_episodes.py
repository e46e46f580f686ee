"""The shipped PPO policy's actions on seeded atlas episodes: tests/test_codec.py's scenarios and their recorder.

This module imports nothing the code before the codec (402136d) lacks, so the fixture tests/data/ppo_actions.json is
recorded with that code and the shipped model files, and test_codec compares the codec's path against the old one:

    T=/tmp/tree402; mkdir -p $T/ov && git archive 402136d | tar -x -C $T
    cp agents/models/ppo_plate.* $T/agents/models/
    ln -s $T/plate_env $T/ov/plate_env && ln -s $T/agents $T/ov/plate_env_agents
    PYTHONPATH=$T/ov python tests/ppo_episodes.py > tests/data/ppo_actions.json

(re-recorded that way whenever the policy is rebuilt).
"""

from __future__ import annotations

import json
import warnings

import numpy as np

from plate_env.env.protocol import ProbeContext
from plate_env.env.rotation import PlateRotationEnv

#: Seeded episodes of the shipped PPO policy: env settings and whether the agent sees the observation.
SCENARIOS = {
    "trained": ({}, True),
    "budget_20": ({"max_probes": 20}, True),
    "budget_40": ({"max_probes": 40}, True),
    "other_coordinates": ({"f_band_hz": (12.0, 36.0), "amplitudes_deg": (12.0, 3.0),
                           "measure_range_s": (0.5, 1.5)}, True),
    "no_observation": ({}, False),
    "other_no_observation": ({"f_band_hz": (12.0, 36.0), "amplitudes_deg": (3.0,), "measure_range_s": (0.5, 1.5)},
                             False),
}
SEEDS = (0, 1)


def ppo_actions(settings: dict, with_obs: bool, seed: int) -> list[list[float]]:
    """The shipped PPO agent's raw actions on one seeded atlas episode (probing until it stops or the env ends)."""
    from plate_env_agents import make_agent

    agent = make_agent("ppo")
    env = PlateRotationEnv(physics="atlas", **settings)
    obs, _ = env.reset(seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        agent.reset(ProbeContext.from_env(env), np.random.default_rng(seed))
    actions = []
    while True:
        action = agent.next_probe(env.table(), obs if with_obs else None)
        if action is None:
            break
        actions.append([float(x) for x in np.asarray(action, dtype=np.float32)])
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    env.close()
    return actions


if __name__ == "__main__":
    print(json.dumps({name: {str(s): ppo_actions(*SCENARIOS[name], s) for s in SEEDS} for name in sorted(SCENARIOS)},
                     indent=0))
