"""The Gymnasium environment PlateRotation-v0: checkers, seeding, rewards, rendering, vector envs, and robustness
(random and malformed actions, memory over many resets)."""

from __future__ import annotations

import copy
import math
import pickle

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import plate_env  # noqa: F401 - registers the environment
from plate_env.env.render import H, W
from plate_env.env.rotation import PlateRotationEnv

FAST = {"tilelink": dict(max_probes=4), "atlas": dict(max_probes=6),
        # pybullet: the contract, not the physics: short probes, and a fixed sheet stiffness (k_elastic) instead of
        # a ring-down calibration per random object (in a fresh clone each reset's object cost one: ~60 s a test)
        "pybullet": dict(max_probes=2, settle_s=0.0, measure_range_s=(0.05, 0.1), method="lorentz",
                         physics_options=dict(n_workers=1, k_elastic=5.0))}


def make(physics="tilelink", **kw):
    return gym.make("PlateRotation-v0", physics=physics, **{**FAST[physics], **kw})


def probe_action(rng):
    a = rng.uniform(-1, 1, 4).astype(np.float32)
    a[3] = -1.0
    return a


@pytest.mark.parametrize("physics", ["tilelink", "atlas", "pybullet"])
def test_gymnasium_and_sb3_check_env(physics):
    from gymnasium.utils.env_checker import check_env

    env = make(physics)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = PlateRotationEnv(physics=physics, **FAST[physics])
    sb3_check(env, warn=False)
    env.close()


def test_namespaced_id_also_registered():
    env = gym.make("plate_env/PlateRotation-v0", physics="atlas")
    assert env.unwrapped.physics.name == "atlas"
    env.close()


def _episode(env, seed, actions):
    out = []
    obs, info = env.reset(seed=seed)
    out.append((obs.copy(), 0.0, env.unwrapped.hidden_object().omega_n))
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append((obs.copy(), r, info["relative_error"]))
        if term or trunc:
            break
    return out


@pytest.mark.parametrize("physics", ["tilelink", "atlas"])
def test_same_seed_same_episode(physics):
    rng = np.random.default_rng(0)
    actions = [probe_action(rng) for _ in range(6)]
    a = _episode(make(physics), 7, actions)
    b = _episode(make(physics), 7, actions)
    c = _episode(make(physics), 8, actions)
    assert len(a) == len(b)
    for (o1, r1, i1), (o2, r2, i2) in zip(a, b, strict=True):
        assert np.array_equal(o1, o2) and r1 == r2 and i1 == i2
    assert not np.array_equal(a[0][0], c[0][0]) or a[0][2] != c[0][2]


def test_reset_draws_the_hidden_object_from_the_object_prior():
    from plate_env.core.objects import ObjectPrior

    env = PlateRotationEnv(physics="atlas", omega_n_range_pi=(5.0, 20.0), alpha_range_deg=(35.0, 50.0))
    for seed in (0, 9):
        env.reset(seed=seed)
        drawn = ObjectPrior((5.0, 20.0), (35.0, 50.0)).draw(np.random.default_rng(seed))
        obj = env.hidden_object()
        assert (obj.omega_n, obj.alpha) == drawn
    env.close()


def test_reward_formula_on_a_hand_made_case():
    env = PlateRotationEnv(physics="atlas", max_probes=3, cost_per_sim_s=0.01, error_cap=1.0)
    env.reset(seed=0, options={"omega_n": 10 * np.pi, "alpha": np.radians(40)})
    rewards, infos = [], []
    for f in (-0.2, 0.0, 0.2):
        _, r, term, _, info = env.step(np.array([f, -1.0, 0.0, -1.0], np.float32))
        rewards.append(r)
        infos.append(info)
    assert term
    sims = np.diff([0.0] + [i["sim_s"] for i in infos])
    np.testing.assert_allclose(rewards[:2], -0.01 * sims[:2])
    est = infos[-1]["estimate"]
    if est["ok"]:
        err = abs(est["omega_n_rad_s"] - 10 * np.pi) / (10 * np.pi)
        assert infos[-1]["relative_error"] == pytest.approx(err)
        assert rewards[-1] == pytest.approx(-0.01 * sims[-1] - min(err, 1.0))
    else:
        assert rewards[-1] == pytest.approx(-0.01 * sims[-1] - 1.0)


def test_stop_without_probes_is_ignored_and_stop_later_ends_with_penalty_when_no_estimate():
    env = PlateRotationEnv(physics="atlas", max_probes=5, method="lorentz", no_estimate_penalty=2.0)
    env.reset(seed=1)
    _, r, term, _, _ = env.step(np.array([0.0, -1.0, 0.0, 1.0], np.float32))  # stop ignored: no probe yet
    assert not term and r < 0
    _, r, term, _, info = env.step(np.array([0.0, -1.0, 0.0, 1.0], np.float32))
    assert term and np.isinf(info["relative_error"]) and r == pytest.approx(-2.0)
    assert not info["estimate"]["ok"] and info["estimate"]["reason"] and info["estimate"]["omega_n_rad_s"] == 0.0


@pytest.mark.parametrize("physics", ["tilelink", "atlas"])
def test_random_episode_ends_within_budget(physics):
    env = make(physics, max_probes=5, max_sim_s=6.0)
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    for n in range(1, 100):  # noqa: B007 - n is the probe count after the loop
        _, r, term, trunc, info = env.step(probe_action(rng))
        assert np.isfinite(r)
        if term or trunc:
            break
    assert n <= 5 and info["probes"] <= 5
    assert info["sim_s"] < 6.0 + 3.0  # at most one probe past the simulated-seconds budget


@pytest.mark.parametrize("bad, message", [
    (np.array([np.nan, 0, 0, -1], np.float32), "NaN"),
    (np.array([2.0, 0, 0, -1], np.float32), "outside the allowed range"),
    (np.zeros(3, np.float32), "shape"),
])
def test_bad_actions_raise_clear_errors_and_keep_history(bad, message):
    env = PlateRotationEnv(physics="atlas", max_probes=5)
    env.reset(seed=0)
    env.step(np.array([0.0, -1.0, 0.0, -1.0], np.float32))
    with pytest.raises(ValueError, match=message):
        env.step(bad)
    assert len(env.table()) == 1
    env.step(np.array([0.1, -1.0, 0.0, -1.0], np.float32))
    assert len(env.table()) == 2


def test_rgb_array_render_and_no_render_by_default():
    env = make("tilelink", render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([0.0, -1.0, 0.0, -1.0], np.float32))
    frame = env.render()
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3
    env.close()
    plain = make("tilelink")
    plain.reset(seed=0)
    assert plain.render() is None


def test_close_twice_and_pickle_and_deepcopy():
    env = PlateRotationEnv(physics="tilelink", max_probes=3)
    env.reset(seed=2)
    env.step(np.array([0.0, -1.0, 0.0, -1.0], np.float32))
    clone = pickle.loads(pickle.dumps(env))
    twin = copy.deepcopy(env)
    a = np.array([0.2, -1.0, 0.0, -1.0], np.float32)
    o1, r1, *_ = env.step(a)
    o2, r2, *_ = clone.step(a)
    o3, r3, *_ = twin.step(a)
    assert np.array_equal(o1, o2) and np.array_equal(o1, o3) and r1 == r2 == r3
    env.close()
    env.close()
    clone.close()


def test_pybullet_close_disconnects_the_client_and_ends_the_workers():
    pb = pytest.importorskip("pybullet")
    import multiprocessing

    from plate_env.physics.pybullet_sheet import PyBulletPhysics

    env = PlateRotationEnv(physics="pybullet", **FAST["pybullet"])
    env.reset(seed=0)
    env.step(np.array([-0.6, -1.0, -1.0, -1.0], np.float32))
    cid = env.physics._client.cid
    assert pb.getConnectionInfo(cid)["isConnected"] == 1
    env.close()
    env.close()
    assert pb.getConnectionInfo(cid)["isConnected"] == 0  # the engine's own view, not our attribute
    with pytest.raises(RuntimeError, match="closed"):  # and no reconnection by a later step
        env.step(np.array([-0.6, -1.0, -1.0, -1.0], np.float32))
    before = {p.pid for p in multiprocessing.active_children()}
    pool = PyBulletPhysics(n_workers=2, n_layer=30, k_elastic=100.0)
    objs = (plate_env.ObjectSpec.from_paper(10.0, 36.9), plate_env.ObjectSpec.from_paper(20.0, 45.0))
    pool.run([plate_env.ProbeSpec(o, plate_env.PlateMotion.from_paper(18.0, 3.0), settle_s=0.1, measure_s=0.1)
              for o in objs])  # two units: the pool runs them
    workers = [p for p in multiprocessing.active_children() if p.pid not in before]
    assert len(workers) == 2 and all(p.is_alive() for p in workers)
    pool.close()
    assert not any(p.is_alive() for p in workers)


@pytest.mark.parametrize("mode", ["vector_entry_point", "async"])
def test_vector_env_equals_n_single_envs(mode):
    kwargs = dict(physics="tilelink", max_probes=3)
    vec = gym.make_vec("PlateRotation-v0", num_envs=3, vectorization_mode=mode, **kwargs)
    ref = gym.make_vec("PlateRotation-v0", num_envs=3, vectorization_mode="sync", **kwargs)
    o1, _ = vec.reset(seed=11)
    o2, _ = ref.reset(seed=11)
    assert np.array_equal(o1, o2)
    rng = np.random.default_rng(11)
    for _ in range(5):
        a = rng.uniform(-1, 1, (3, 4)).astype(np.float32)
        a[:, 3] = -1
        s1, s2 = vec.step(a), ref.step(a)
        for x, y in zip(s1[:4], s2[:4], strict=True):
            assert np.array_equal(x, y)
    vec.close()
    ref.close()


@pytest.mark.parametrize("mode", ["vector_entry_point", "sync"])
def test_vector_infos_batch_episode_ends_with_and_without_estimates(mode):
    """Gymnasium batches each info key into one array: a key that is None in one sub-env and a number or a dict in
    another used to crash it (estimate.check.worst, estimate.bound, relative_error). Random stops make some
    episodes end without an estimate (a single probe) and others with one; relative_error is a float64 array, inf
    where there is no estimate."""
    vec = gym.make_vec("PlateRotation-v0", num_envs=4, vectorization_mode=mode, physics="atlas", max_probes=6)
    vec.reset(seed=3)
    rng = np.random.default_rng(3)
    with_est = without = 0
    for _ in range(120):
        a = rng.uniform(-1, 1, (4, 4)).astype(np.float32)
        a[:, 3] = np.where(rng.uniform(size=4) < 0.3, 1.0, -1.0)
        _, _, term, _, info = vec.step(a)
        if term.any():
            ok = info["estimate"]["ok"][term].astype(bool)
            has_error = np.isfinite(info["relative_error"])
            assert np.array_equal(has_error[term], ok)  # an error exactly where there is an estimate
            with_est, without = with_est + int(ok.sum()), without + int((~ok).sum())
    assert with_est > 0 and without > 0
    vec.close()


def test_pybullet_rgb_array_draws_the_same_frame():
    pytest.importorskip("pybullet")
    env = PlateRotationEnv(physics="pybullet", render_mode="rgb_array", **FAST["pybullet"])
    env.reset(seed=0)
    env.step(np.array([-0.6, -1.0, -1.0, -1.0], np.float32))
    frame = env.render()
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 10
    env.close()
    assert env._renderer is None


PROPERTY = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])


@pytest.fixture(scope="module")
def atlas_env():
    env = PlateRotationEnv(physics="atlas", max_probes=6)
    yield env
    env.close()


ACTIONS = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=4, max_size=4),
    st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4),
    st.lists(st.floats(-1.0, 1.0), min_size=0, max_size=7),
    st.lists(st.floats(-3.0, 3.0), min_size=4, max_size=4),
    st.sampled_from(["abc", None, [[0.0, 0.0, 0.0, 0.0]], {"a": 1}, [0.0, 0.0, 0.0, "x"]]),
)


@PROPERTY
@given(seed=st.integers(0, 2 ** 31 - 1), actions=st.lists(ACTIONS, min_size=1, max_size=12))
def test_env_step_valid_or_valueerror(atlas_env, seed, actions):
    env = atlas_env
    obs, info = env.reset(seed=seed)
    assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
    for action in actions:
        try:
            obs, reward, terminated, truncated, info = env.step(action)
        except ValueError as exc:  # a clear refusal names the bad value
            assert str(exc)
            continue
        assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
        assert math.isfinite(reward)
        if terminated or truncated:
            obs, info = env.reset(seed=seed + 1)
            assert np.all(np.isfinite(obs))


def _rss_bytes() -> int:
    """Resident set size of this process from /proc/self/statm (pages -> bytes)."""
    import os

    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_env_resets_keep_rss_flat():
    env = PlateRotationEnv(physics="atlas", max_probes=4)
    action = np.array([0.1, -0.5, 0.0, -1.0], dtype=np.float32)
    for i in range(100):  # warm up caches and allocator pools
        env.reset(seed=i)
        env.step(action)
    before = _rss_bytes()
    for i in range(1000):
        env.reset(seed=1000 + i)
        env.step(action)
    grown = _rss_bytes() - before
    env.close()
    assert grown < 8 * 2 ** 20, f"RSS grew {grown / 2 ** 20:.1f} MiB over 1000 resets"


def test_the_spec_bounds_every_episode_and_cuts_none_short():
    """Issue 28 item 22: the registered spec's max_episode_steps is the largest max_probes the env accepts, so a
    TimeLimit bounds every episode and never truncates one the env would end itself; a smaller limit passed to
    gym.make or gym.make_vec truncates at it in both."""
    from plate_env.core.setup import MAX_PROBES_RANGE

    assert gym.spec("PlateRotation-v0").max_episode_steps == MAX_PROBES_RANGE[1] == 500
    with pytest.raises(ValueError, match="max_probes"):
        PlateRotationEnv(physics="atlas", max_probes=MAX_PROBES_RANGE[1] + 1)
    go = np.array([0.0, 0.0, 0.0, -1.0], dtype=np.float32)  # probe, never stop
    for limit, (steps, term, trunc) in ((None, (6, True, False)), (4, (4, False, True))):
        env = gym.make("PlateRotation-v0", physics="atlas", max_probes=6,
                       **({} if limit is None else {"max_episode_steps": limit}))
        env.reset(seed=0)
        n, done = 0, (False, False)
        while not any(done):
            *_, te, tr, _ = env.step(go)
            n, done = n + 1, (te, tr)
        assert (n, *done) == (steps, term, trunc)
        env.close()
        vec = gym.make_vec("PlateRotation-v0", num_envs=2, vectorization_mode="vector_entry_point", physics="atlas",
                           max_probes=6, **({} if limit is None else {"max_episode_steps": limit}))
        vec.reset(seed=0)
        for _ in range(steps):
            _, _, te, tr, _ = vec.step(np.tile(go, (2, 1)))
        assert (te.tolist(), tr.tolist()) == ([term] * 2, [trunc] * 2), limit
        vec.close()
