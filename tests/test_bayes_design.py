"""The bayes agent's vectorised design (every candidate at once, blurred moments, numba sums) chooses what the
candidate-by-candidate loop it replaced chooses, with the same expected utilities up to rounding."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from plate_env.env import PlateRotationEnv
from plate_env.env.protocol import Probe, ProbeContext
from plate_env.identify.inference import blurred, log_student
from plate_env_agents import make_agent
from plate_env_agents.bayes import SE_1S


def _loop_choice(agent, history) -> tuple[Probe | None, float]:
    """The design as the agent computed it before (690d019): candidate by candidate, each outcome's likelihood
    blurred on the grid. The same draws from the agent's generator."""
    posts, wts = agent._member_posts()
    k_mem = len(agent.fm.members)
    v0 = float(agent._pooled_var(posts, wts))
    best, best_u = None, -np.inf
    for a in agent.amps:
        per = agent.tables[a]
        done = history.f_p_hz[np.isclose(history.a_p_deg, a)]
        members = agent.rng.choice(k_mem, size=agent.n_samples, p=wts)
        cells = np.array([agent.rng.choice(posts[j].size, p=posts[j].ravel()) for j in members])
        z = agent.rng.normal(size=agent.n_samples)
        for i_f in range(len(agent.freqs)):
            if np.any(np.abs(done - agent.freqs[i_f]) < 0.5 * agent.f_step_hz):
                continue
            if all(t is None or not t[0][i_f] for t in per):
                continue
            pu = np.stack([np.exp(blurred(np.log(t[3][i_f]), agent.blur_steps[j])) if (t is not None and t[0][i_f])
                           else np.ones((len(agent.omega), agent.n_alpha)) for j, t in enumerate(per)])
            covers = np.array([t is not None and bool(t[0][i_f]) for t in per])
            p_un = float(np.sum(wts * np.where(covers, (posts * pu).sum(axis=(1, 2)), 0.0)))
            post_un = np.where(covers[:, None, None], posts * pu, posts)
            var_un = float(agent._pooled_var(post_un, wts)) if p_un > 0 else v0
            for window in agent.windows:
                se2 = SE_1S ** 2 / window
                y = np.empty(agent.n_samples)
                for s_i, (j, c) in enumerate(zip(members, cells, strict=True)):
                    t = per[j]
                    if t is None or not t[0][i_f]:
                        y[s_i] = np.nan
                        continue
                    y[s_i] = t[1][i_f].ravel()[c] + z[s_i] * math.sqrt(
                        t[2][i_f].ravel()[c] ** 2 + se2 + agent.fm.members[j].sigma_model ** 2)
                valid = ~np.isnan(y)
                if not valid.any():
                    continue
                yv = y[valid][:, None, None]
                like = np.ones((int(valid.sum()), k_mem, len(agent.omega), agent.n_alpha))
                for j, t in enumerate(per):
                    if t is not None and t[0][i_f]:
                        mu, s, p = t[1][i_f], t[2][i_f], t[3][i_f]
                        var = s ** 2 + se2 + agent.fm.members[j].sigma_model ** 2
                        like[:, j] = np.exp(blurred(np.log1p(-p)[None] + log_student(yv - mu[None], var[None]),
                                                    agent.blur_steps[j]))
                var_st = float(np.mean(agent._pooled_var(posts[None] * like, wts[None])))
                expected = p_un * var_un + (1 - p_un) * var_st
                cost = agent.context.overhead_s + window * (1 - p_un) + 0.5 * window * p_un
                u = (v0 - expected) / cost
                if u > best_u:
                    best_u, best = u, Probe(float(agent.freqs[i_f]), a, window)
    return best, best_u


@pytest.mark.parametrize("seed", [0, 3])
def test_vectorised_design_chooses_the_loops_probe(seed):
    env = PlateRotationEnv(physics="atlas", max_probes=8)
    agent = make_agent("bayes", target_rel=0.0)
    env.reset(seed=seed)
    agent.reset(ProbeContext.from_env(env), np.random.default_rng(seed))
    for _ in range(5):  # the prior's full grid first, then posteriors that concentrate (cells pruned)
        history = env.table()
        before = copy.deepcopy(agent.rng.bit_generator.state)
        choice = agent.next_probe(history)
        after = agent.rng.bit_generator.state
        agent.rng.bit_generator.state = before  # the reference loop draws from the same generator state
        want, _ = _loop_choice(agent, history)
        assert choice == want
        assert agent.rng.bit_generator.state == after  # the same draws, no more
        env.step(env.encode_action(choice.f_p_hz, choice.a_p_deg, choice.measure_s))
