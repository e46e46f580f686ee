"""The env's info contract (issues 38 and 41): one schema declared in plate_env.env.info, every key on every step
with a fixed numpy dtype, the hidden object only on the terminating step, observation and info agreeing on each
probe, and the batching/logging clients that tripped on keys that came and went."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import plate_env  # noqa: F401 - registers the environment
from plate_env.env import info as schema
from plate_env.env.rotation import PlateRotationEnv

#: The dtype each schema dtype must have in an info.
DTYPES = {"float64": np.float64, "int64": np.int64, "bool": np.bool_}


def _random_episodes(env, steps: int, seed: int = 0, p_stop: float = 0.25):
    """(reset info, [(obs, terminated, info), ...]) per episode over ``steps`` random steps; a random stop bit makes
    some episodes end after one probe (no estimate) and others run their budget."""
    rng = np.random.default_rng(seed)
    episodes, done_steps, ep = [], 0, 0
    while done_steps < steps:
        _, first = env.reset(seed=seed + ep)
        ep += 1
        rows, term = [], False
        while not term:
            a = rng.uniform(-1, 1, 4).astype(np.float32)
            a[3] = 1.0 if rng.uniform() < p_stop else -1.0
            obs, _, term, trunc, info = env.step(a)
            rows.append((obs, term, info))
            done_steps += 1
            assert not trunc
        episodes.append((first, rows))
    return episodes


@pytest.fixture(scope="module")
def episodes():
    env = PlateRotationEnv(physics="atlas", max_probes=6)
    out = _random_episodes(env, 1200)
    yield env, out
    env.close()


def test_every_key_on_every_step_with_its_dtype(episodes):
    """Issue 41 item 5 / 38 item 1: >= 1,000 atlas steps, episodes with and without an estimate: every info (reset
    and step) has exactly the declared keys, each of its declared type, none NaN; relative_error is inf exactly
    where the estimate is not ok; the nested fields that came and went (bound, reason, check.worst) are always there."""
    _, eps = episodes
    steps = sum(len(rows) for _, rows in eps)
    assert steps >= 1000
    keys = {f.key for f in schema.FIELDS}
    with_est = without = 0
    for first, rows in eps:
        for info in [first] + [r[2] for r in rows]:
            assert schema.problems(info) == [], schema.problems(info)
            assert set(schema.flatten(info)) == keys
            assert not [k for k, v in schema.flatten(info).items() if isinstance(v, np.floating) and np.isnan(v)]
        final = rows[-1][2]
        ok = bool(final["estimate"]["ok"])
        assert math.isinf(final["relative_error"]) != ok
        assert final["estimate"]["reason"] == "" if ok else final["estimate"]["reason"]
        with_est, without = with_est + ok, without + (not ok)
    assert with_est >= 20 and without >= 5, (with_est, without)


def test_info_values_are_numpy_scalars_of_fixed_dtypes(episodes):
    """Issue 41 item 6: no plain Python int/float/bool in any info (torchrl's info reader needs ``.dtype``): every
    number is a numpy float64, int64 or bool_ scalar, a string a str, whatever the step."""
    _, eps = episodes
    by_key: dict[str, set] = {}
    for first, rows in eps[:60]:
        for info in [first] + [r[2] for r in rows]:
            for k, v in schema.flatten(info).items():
                by_key.setdefault(k, set()).add(np.dtype(v).name if isinstance(v, np.generic) else
                                                "str" if isinstance(v, str) else f"python {type(v).__name__}")
    plain = {k: sorted(v) for k, v in by_key.items() if any(t.startswith("python ") for t in v)}
    assert not plain, plain  # e.g. {"sim_s": ["python float"], "probes": ["python int"]} before
    declared = {f.key: f.dtype for f in schema.FIELDS}
    assert {k: sorted(v) for k, v in by_key.items()} == {k: [declared.get(k, "undeclared")] for k in by_key}


def test_names_carry_one_unit_each():
    """Issue 41 item 6: a quantity's unit is in its name (alpha_true was radians beside last_probe.alpha_deg):
    every field with a unit ends in that unit, and the old unit-less truth keys are gone."""
    suffix = {"rad/s": "_rad_s", "rad": "_rad", "kg": "_kg", "deg": "_deg", "g": "_g", "Hz": "_hz", "mm": "_mm",
              "s": "_s", "deg/s": "_deg_s", "pi rad/s": "_pi"}
    for f in schema.FIELDS:
        if f.unit != "-":
            assert f.key.endswith(suffix[f.unit]), f
    env = PlateRotationEnv(physics="atlas", max_probes=3)
    _, info = env.reset(seed=0)
    assert {"omega_n_true_rad_s", "alpha_true_rad", "mass_true_kg"} <= set(info)
    assert not {"omega_n_true", "alpha_true", "mass_true"} & set(info)


def test_the_hidden_object_only_on_the_terminating_step(episodes):
    """Issue 38 item 2: before the terminating step no info holds the hidden object (the truth keys are 0 and no
    other number equals omega_n, alpha or the mass in any unit); the terminating step holds it exactly."""
    env, eps = episodes
    for first, rows in eps:
        *_, (_, _, final) = rows
        truth = (final["omega_n_true_rad_s"], final["alpha_true_rad"], final["mass_true_kg"])
        secret = {truth[0], truth[1], math.degrees(truth[1]), truth[2], truth[2] * 1e3}
        for info in [first] + [r[2] for r in rows[:-1]]:
            flat = schema.flatten(info)
            assert not info["truth_revealed"]
            assert all(flat[k] == 0.0 for k in schema.HIDDEN_KEYS)
            assert not secret & {float(v) for v in flat.values() if isinstance(v, np.floating)}
        assert final["truth_revealed"] and all(np.isfinite(truth))
        assert final["last_probe"]["omega_n_rad_s"] == truth[0]
        assert final["last_probe"]["mass_g"] == pytest.approx(truth[2] * 1e3)
    obj = env.hidden_object()
    assert (eps[-1][1][-1][2]["omega_n_true_rad_s"], eps[-1][1][-1][2]["alpha_true_rad"]) == (obj.omega_n, obj.alpha)


def test_reveal_truth_shows_it_on_every_step():
    """Diagnostics: reveal_truth=True puts the hidden object in every info, reset included; anything but a bool
    is refused."""
    env = PlateRotationEnv(physics="atlas", max_probes=3, reveal_truth=True)
    _, info = env.reset(seed=5, options={"omega_n": 40.0})
    assert info["truth_revealed"] and info["omega_n_true_rad_s"] == 40.0
    _, _, term, _, info = env.step(env.encode_action(20.0, 3.0, 1.0))
    assert not term and info["omega_n_true_rad_s"] == 40.0 and info["last_probe"]["omega_n_rad_s"] == 40.0
    with pytest.raises(ValueError, match="reveal_truth"):
        PlateRotationEnv(physics="atlas", reveal_truth="yes")


def test_run_episode_scores_the_truth_even_when_its_budget_stops_the_episode():
    """run_episode reads the truth from the env, not the info: a max_sim_s budget of its own ends the episode on a
    non-final step, whose info hides the object."""
    from plate_env.env.episode import run_episode
    from plate_env.env.protocol import Agent, Probe

    class Sweep(Agent):
        name = "sweep"

        def next_probe(self, history, obs=None):
            return Probe(12.0 + 2.0 * len(history), 3.0, 1.0)

    env = PlateRotationEnv(physics="atlas", max_probes=20)
    res = run_episode(env, Sweep(), seed=3, options={"omega_n": 50.0, "alpha": 0.7}, max_sim_s=5.0)
    assert res.n_probes < 20 and (res.omega_n_true, res.alpha_true) == (50.0, 0.7)


def test_observation_and_info_hold_the_same_omega_b(episodes):
    """Issue 41 item 4: the observation's omega_B and info["last_probe"]["omega_b_deg_s"] are one value, the
    camera's measurement, on every probe; 0 in both for an unstable probe (it has no rotation rate), and its
    standard error too."""
    env, eps = episodes
    n_unstable = n_stable = 0
    for _, rows in eps:
        for obs, _, info in rows:
            p = info["last_probe"]
            slot = min(int(info["probes"]), env.max_probes) - 1
            row = obs[7 * slot: 7 * slot + 7]
            assert p["ok"] and bool(row[4]) == bool(p["unstable"])
            assert p["omega_b_deg_s"] == pytest.approx(float(row[2]) * 1000.0, rel=1e-6, abs=1e-3)
            assert p["stderr_deg_s"] == pytest.approx(float(row[3]) * 1000.0, rel=1e-6, abs=1e-3)
            if p["unstable"]:
                assert p["omega_b_deg_s"] == 0.0 and p["stderr_deg_s"] == 0.0 and p["reason"]
                n_unstable += 1
            else:
                assert p["reason"] == ""
                n_stable += 1
    assert n_unstable >= 50 and n_stable >= 50, (n_unstable, n_stable)


def test_the_schema_is_declared_once_and_rendered_in_the_docs():
    """The env's docstring and docs/env.md show the table of plate_env.env.info.FIELDS; build refuses a key that
    is not declared there."""
    from pathlib import Path

    doc = PlateRotationEnv.__doc__
    assert all(f"| ``{f.key}`` | {f.dtype} | {f.unit} |" in doc for f in schema.FIELDS)
    page = (Path(__file__).resolve().parents[1] / "docs" / "env.md").read_text()
    assert schema.markdown() in page
    with pytest.raises(KeyError, match="not declared"):
        schema.build({"omega_n_true": 1.0})


def test_gymnasium_checker_and_equal_infos_for_equal_seeds():
    """Gymnasium's check_env (which compares step infos with ==) passes and two runs of the same seeds give equal
    infos: no value is NaN (a NaN never equals itself)."""
    from gymnasium.utils.env_checker import check_env

    check_env(PlateRotationEnv(physics="atlas", max_probes=4), skip_render_check=True)
    a = _random_episodes(PlateRotationEnv(physics="atlas", max_probes=4), 30, seed=9)
    b = _random_episodes(PlateRotationEnv(physics="atlas", max_probes=4), 30, seed=9)
    for (fa, ra), (fb, rb) in zip(a, b, strict=True):
        assert fa == fb
        for (_, _, ia), (_, _, ib) in zip(ra, rb, strict=True):
            ia, ib = dict(ia), dict(ib)
            ia.pop("wall_s"), ib.pop("wall_s")  # the one non-deterministic number
            assert ia == ib


@pytest.mark.parametrize("mode", ["sync", "vector_entry_point"])
def test_gymnasium_vector_infos_hold_every_key_for_every_sub_env(mode):
    """Gymnasium's vector modes batch the info into arrays of the field's dtype with a mask that is True for every
    sub-environment on every step (no key missing anywhere)."""
    vec = gym.make_vec("PlateRotation-v0", num_envs=3, vectorization_mode=mode, physics="atlas", max_probes=4)
    _, infos = vec.reset(seed=1)
    rng = np.random.default_rng(1)
    for _ in range(40):
        a = rng.uniform(-1, 1, (3, 4)).astype(np.float32)
        _, _, _, _, infos = vec.step(a)
        flat = schema.flatten(infos)
        for f in schema.FIELDS:
            *parent, leaf = f.key.split(".")
            mask = flat[".".join([*parent, f"_{leaf}"])]
            assert mask.all(), f.key
            if f.dtype in ("float64", "int64"):
                assert flat[f.key].dtype == DTYPES[f.dtype], f.key
    vec.close()


def test_sb3_monitor_logs_relative_error_for_every_episode():
    """Issue 41 item 5: Monitor(info_keywords=("relative_error",)) raised KeyError at the first episode without an
    estimate; now every episode logs it, inf without an estimate."""
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.monitor import Monitor

    env = Monitor(gym.make("PlateRotation-v0", physics="atlas", max_probes=4), info_keywords=("relative_error",))
    rng = np.random.default_rng(0)
    errors = []
    for ep in range(60):
        env.reset(seed=ep)
        term = trunc = False
        while not (term or trunc):
            a = rng.uniform(-1, 1, 4).astype(np.float32)
            a[3] = 1.0 if rng.uniform() < 0.4 else -1.0
            _, _, term, trunc, info = env.step(a)
        errors.append(info["episode"]["relative_error"])
    assert np.isinf(errors).any() and np.isfinite(errors).any() and not np.isnan(errors).any()
    env.close()


def test_tianshou_collector_batches_the_infos_and_its_trainer_accepts_them():
    """Issue 38 item 1: tianshou's Collector over a DummyVectorEnv stacked infos into a Batch and raised "Creating
    keys is not supported by item assignment" when a key appeared on some steps only; and its trainers refuse a
    buffer holding a NaN anywhere, info included ("Encountered NaNs in buffer"), so no info value may be NaN."""
    pytest.importorskip("tianshou")
    from tianshou.algorithm.algorithm_base import RandomActionPolicy
    from tianshou.data import Collector, VectorReplayBuffer
    from tianshou.env import DummyVectorEnv

    envs = DummyVectorEnv([lambda: gym.make("PlateRotation-v0", physics="atlas", max_probes=6) for _ in range(4)])
    collector = Collector(RandomActionPolicy(envs.action_space[0]), envs, VectorReplayBuffer(2000, 4))
    collector.reset()
    stats = collector.collect(n_step=800)
    assert stats.n_collected_episodes >= 20
    buf = collector.buffer
    assert not buf.hasnull()  # the check tianshou's OnPolicyTrainer/OffPolicyTrainer make after every collect
    data = buf[:]  # every stored step (a VectorReplayBuffer's arrays hold empty slots between its sub-buffers)
    err, done = data.info.relative_error, data.done
    assert err.dtype == np.float64 and np.isinf(err[done]).any() and np.isfinite(err[done]).any()
    assert np.isinf(err[~done]).all()  # no estimate before the terminating step
    envs.close()


def test_the_v0_training_id_runs_v0_on_the_atlas():
    """Issue 41 item 2: PlateRotationAtlas-v0 is v0 on the point mass's atlas (the same contract, microsecond
    probes), and the env's docstring says which ids train and which evaluate."""
    env = gym.make("PlateRotationAtlas-v0")
    live = gym.make("PlateRotation-v0")
    assert env.unwrapped.physics_name == "atlas" and live.unwrapped.physics_name == "tilelink"
    assert env.unwrapped.model == live.unwrapped.model == "pointmass"
    assert env.observation_space == live.observation_space and env.action_space == live.action_space
    ids = PlateRotationEnv.__doc__.split("## Ids: training and evaluation")[1]
    assert "PlateRotationAtlas-v0" in ids and "evaluation" in ids and "train" in ids
    env.close()
    live.close()
