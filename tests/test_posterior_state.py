"""The incremental PosteriorState equals the from-scratch posterior (bit for bit: same floats, tolerance 0), and the
env, run_episode and the benchmark's prefixes read it."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify
from plate_env.identify.forward import ForwardModel, Member, load_forward_model
from plate_env.identify.inference import (
    blurred,
    identify_atlas,
    member_domain,
    member_response,
    pool,
    posterior,
    probe_log_likelihood,
)
from plate_env.identify.posterior_state import PosteriorState
from plate_env.surrogate.conditioning import KnownInputs


def _episode_table(seed: int, n: int, amps=(3.0, 12.0), band=(10.0, 40.0)) -> ProbeTable:
    """Probes of a hidden object answered by the atlas physics (seeded), some unstable."""
    from plate_env.env.rotation import PlateRotationEnv

    env = PlateRotationEnv(physics="atlas", amplitudes_deg=amps, f_band_hz=band, max_probes=n)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(n):
        env.step(env.encode_action(rng.uniform(*band), amps[int(rng.integers(len(amps)))], rng.uniform(0.5, 2.0)))
    return env.table()


@pytest.fixture(scope="module")
def two_members() -> ForwardModel:
    """The point-mass model (3 and 12 deg) pooled with the rigid-limit one (3 deg only, 10-40 Hz): a probe at 12 deg
    is left out of the second member, so the evidences compare the common probes only."""
    pm = load_forward_model("tilelink/pointmass")
    rl = load_forward_model("tilelink/rigid_limit")
    return ForwardModel(name="two", members=(pm.members[0], rl.members[0]), sigma_eps=0.05, eps_nu=3.0,
                        offset_sigma=0.02, offset_nu=2.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_incremental_equals_from_scratch_one_member(seed):
    fm = load_forward_model("tilelink/pointmass")
    table = _episode_table(seed, 8)
    state = PosteriorState(fm)
    for k in range(len(table)):
        state.add(table.f_p_hz[k], table.a_p_deg[k], table.omega_b_deg_s[k], table.stderr_deg_s[k], table.unstable[k])
        prefix = table.subset(np.arange(len(table)) <= k)
        ref = posterior(fm, prefix)
        got = state.posterior()
        assert np.array_equal(got.prob, ref.prob)  # tolerance 0: the same additions in the same order
        assert got.member_weights == ref.member_weights and got.skipped == ref.skipped
        assert state.estimate().to_dict() == identify_atlas(prefix, fm).to_dict()


def test_incremental_equals_from_scratch_members_and_skips(two_members):
    table = _episode_table(5, 10)
    assert np.any(np.isclose(table.a_p_deg, 12.0)) and np.any(np.isclose(table.a_p_deg, 3.0))
    state = PosteriorState(two_members)
    ests = state.prefix_estimates(table)
    for k, est in enumerate(ests):
        prefix = table.subset(np.arange(len(table)) <= k)
        ref = identify_atlas(prefix, two_members)
        assert est.to_dict() == ref.to_dict()
        if est.posterior is not None:
            assert np.array_equal(est.posterior.prob, ref.posterior.prob)
    assert state.skipped[1] == int(np.isclose(table.a_p_deg, 12.0).sum()) > 0


def test_orphan_probe_and_empty_state_match_identify_atlas(two_members):
    state = PosteriorState(two_members)
    empty = ProbeTable.from_arrays([], [], [])
    assert state.estimate().to_dict() == identify_atlas(empty, two_members).to_dict()
    table = ProbeTable.from_arrays([20.0, 22.0], [3.0, 7.0], [40.0, 45.0], [1.0, 1.0])  # 7 deg: no member has it
    state.add_table(table)
    est = state.estimate()
    assert not est.ok and "7" in est.reason
    assert est.to_dict() == identify_atlas(table, two_members).to_dict()


def test_design_state_equals_the_agents_former_sums():
    """The bayes agent's state (whole grid, its own blur, members compared on their own probes) equals the sums the
    agent computed before it used PosteriorState."""
    fm = load_forward_model("tilelink/pointmass")
    w, a = fm.grid(81, 16)
    blur = [math.hypot(m.blur, 0.04) for m in fm.members]
    table = _episode_table(3, 6)
    state = PosteriorState(fm, grid=(w, a), blurs=blur, member_rows_only=False, compare_on_common=False)
    state.add_table(table)
    step = math.log(w[1] / w[0])
    lls = [np.zeros((len(w), len(a))) for _ in fm.members]
    for k in range(len(table)):
        f, amp = float(table.f_p_hz[k]), float(table.a_p_deg[k])
        for i, m in enumerate(fm.members):
            if member_domain(m, f, amp) is None:
                mu, s, p = member_response(m, amp, w, a)[0](f)
                lls[i] += blurred(probe_log_likelihood(mu, s, p, float(table.omega_b_deg_s[k]),
                                                       float(table.stderr_deg_s[k]), bool(table.unstable[k]),
                                                       m.sigma_model, m.atlas.n_repeats), blur[i] / step)
    for got, ref in zip(state.log_likes, lls, strict=True):
        assert np.array_equal(got, ref)
    import dataclasses

    ref_post = pool(dataclasses.replace(fm, sigma_eps=0.0, offset_sigma=0.0), w, a, lls)
    assert np.array_equal(state.posterior(discrepancy=False).prob, ref_post.prob)


def test_blurs_must_match_members():
    fm = load_forward_model("tilelink/pointmass")
    with pytest.raises(ValueError, match="one per member"):
        PosteriorState(fm, blurs=[0.1, 0.2])


def test_env_episode_end_reads_the_state_and_equals_identify():
    from plate_env.env.rotation import PlateRotationEnv

    env = PlateRotationEnv(physics="atlas", max_probes=5)
    env.reset(seed=11)
    info = {}
    for f in (14.0, 18.0, 22.0, 26.0, 30.0):
        *_, info = env.step(env.encode_action(f, 3.0, 1.0))
    assert "estimate" in info
    ref = identify(env.table(), method="atlas", physics="tilelink", model="pointmass", known=env.known_inputs())
    from plate_env.env.info import build, estimate_values

    assert info["estimate"] == build(estimate_values(ref))["estimate"]
    assert info["estimate"]["omega_n_rad_s"] == ref.omega_n and info["estimate"]["ok"] == ref.ok
    assert env.posterior_state().n_probes == 5  # one state, each probe added once
    clone = pickle.loads(pickle.dumps(env))  # the state is not pickled: rebuilt from the probes
    assert clone.episode.posterior is None and clone.estimate().to_dict() == ref.to_dict()


def test_env_state_missing_forward_model_gives_reason(monkeypatch):
    from plate_env.env.rotation import PlateRotationEnv

    env = PlateRotationEnv(physics="atlas", max_probes=3)
    env.reset(seed=0)
    env.step(env.encode_action(20.0, 3.0, 1.0))
    import dataclasses

    from plate_env.identify.estimators import ForwardName

    no_model = dataclasses.replace(env.task, forward=ForwardName(env.source, "no_such_model"))
    monkeypatch.setattr(env.episode, "task", no_model)
    est = env.estimate()
    assert not est.ok and "no_such_model" in est.reason


def test_run_episode_prefix_estimates_equal_from_scratch():
    from plate_env.env.episode import estimate_model_of, estimate_of, run_episode
    from plate_env.env.rotation import PlateRotationEnv
    from plate_env_agents import make_agent

    env = PlateRotationEnv(physics="atlas", max_probes=6)
    for name in ("grid", "bayes"):
        agent = make_agent(name)
        res = run_episode(env, agent, seed=4, prefix=True)
        t = res.probes
        fm = estimate_model_of(agent)
        ref = [estimate_of(env, t.subset(np.arange(len(t)) < k), agent.method, fm).to_dict()
               for k in range(1, len(t) + 1)]
        assert [e.to_dict() for e in res.prefix] == ref
        assert res.estimate.to_dict() == ref[-1]
        plain = run_episode(env, make_agent(name), seed=4)
        assert plain.estimate.to_dict() == ref[-1] and plain.prefix == ()


def test_known_inputs_condition_the_state():
    fm = load_forward_model("tilelink/pointmass", KnownInputs(mass=0.02))
    table = _episode_table(1, 4)
    assert np.array_equal(PosteriorState(fm).posterior().prob, posterior(fm, ProbeTable.from_arrays([], [], [])).prob)
    state = PosteriorState(fm)
    state.add_table(table)
    assert np.array_equal(state.posterior().prob, posterior(fm, table).prob)
    assert isinstance(fm.members[0], Member)
