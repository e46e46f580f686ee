"""The observation/action codec of PlateRotation-v0 (plate_env.env.codec), shared by the env and the PPO agent.

The shipped PPO policy must act as it did before the codec existed: tests/data/ppo_actions.json holds its actions
on seeded episodes (the training settings, other budgets, another band/amplitudes/windows, and acting without an
observation), recorded with the code of commit 402136d, before the env and the agent shared the codec, and the shipped
model files (tests/ppo_episodes.py says how; re-recorded that way when the policy was rebuilt); the tests replay the
episodes and compare the actions bit for bit.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from ppo_episodes import SCENARIOS, SEEDS, ppo_actions

from plate_env.env.codec import N_FEATURES, Codec
from plate_env.env.rotation import PlateRotationEnv

RECORD = Path(__file__).parent / "data" / "ppo_actions.json"


@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_the_ppo_policy_acts_as_before_the_codec(scenario):
    recorded = json.loads(RECORD.read_text())
    settings, with_obs = SCENARIOS[scenario]
    for seed in SEEDS:
        expected = recorded[scenario][str(seed)]
        assert len(expected) >= 3  # the policy probed
        assert ppo_actions(settings, with_obs, seed) == expected


TRAINED = Codec((10.0, 40.0), (3.0, 12.0), (0.25, 2.0), 30)
OTHER = Codec((12.0, 36.0), (12.0, 3.0), (0.5, 1.5), 20)


def test_an_action_decodes_to_the_probe_it_encodes():
    for f, a_p, w in ((10.0, 3.0, 0.25), (23.5, 12.0, 1.1), (40.0, 12.0, 2.0)):
        assert TRAINED.decode(TRAINED.encode(f, a_p, w).astype(np.float64)) == pytest.approx((f, a_p, w), rel=1e-6)
    np.testing.assert_array_equal(TRAINED.encode(55.0, 3.0, 9.0), [1.0, -0.5, 1.0, -1.0])  # clipped, first slice
    with pytest.raises(ValueError, match="not one of this env's amplitudes"):
        TRAINED.encode(20.0, 6.0, 1.0)


def test_rows_and_actions_translated_between_codecs_mean_the_same_probes():
    rows = [(14.0, 3.0, 250.0, 4.0, False, 0.75), (30.5, 12.0, -80.0, 2.5, True, 1.25)]
    translated = TRAINED.rows_from(OTHER.observation(rows, 0.9, 0.5)[: TRAINED.obs_dim], 2, OTHER)
    direct = TRAINED.observation(rows, 0.9, 0.5)
    np.testing.assert_allclose(translated[: 2 * N_FEATURES], direct[: 2 * N_FEATURES], atol=1e-6)
    action = OTHER.encode(30.0, 3.0, 1.0)
    assert TRAINED.decode(TRAINED.action_from(action, OTHER).astype(np.float64)) == pytest.approx((30.0, 3.0, 1.0))
    assert TRAINED.action_from(action, TRAINED) is action  # same coordinates: untouched


def test_the_env_observation_is_the_codecs():
    env = PlateRotationEnv(physics="atlas", max_probes=5)
    env.reset(seed=3)
    obs = None
    for f in (15.0, 25.0):
        obs, *_ = env.step(env.encode_action(f, 12.0, 0.5))
    t = env.table()
    rows = [(t.f_p_hz[i], t.a_p_deg[i], t.omega_b_deg_s[i], t.stderr_deg_s[i], t.unstable[i], 0.5) for i in range(2)]
    np.testing.assert_array_equal(obs, env.codec.observation(rows, 1.0 - 2 / 5, 1.0))
    assert obs.shape == (env.codec.obs_dim,) == env.observation_space.shape and obs[2 * N_FEATURES - 1] == 1.0
    env.close()


def test_an_observation_is_resized_to_another_slot_count():
    obs = OTHER.observation([(20.0, 3.0, 100.0, 1.0, False, 1.0)] * 3, 0.85, 0.4)
    out = TRAINED.resized(obs, 3)
    assert out.shape == (TRAINED.obs_dim,) and out[-2] == pytest.approx(0.9) and out[-1] == pytest.approx(0.4)
    np.testing.assert_array_equal(out[: 3 * N_FEATURES], obs[: 3 * N_FEATURES])
    with pytest.raises(ValueError, match="not a PlateRotation-v0 observation"):
        TRAINED.resized(np.zeros(10), 0)
