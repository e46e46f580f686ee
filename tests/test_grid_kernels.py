"""The numba kernels of plate_env.core.grid_kernels give the numpy code's floats bit for bit (signed zeros and NaN
included), and plate_env.core.jit switches to them only as documented."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.core import jit
from plate_env.core.probe_table import ProbeTable
from plate_env.identify import inference as inf
from plate_env.identify.forward import load_forward_model
from plate_env.identify.posterior_state import PosteriorState
from plate_env.surrogate.atlas import load_atlas


@pytest.fixture(autouse=True)
def _restore_jit():
    yield
    jit.force(None)


def both(fn):
    """``fn()`` with the numpy code, then with the kernels."""
    jit.force(False)
    a = fn()
    jit.force(True)
    b = fn()
    return a, b


def same(a, b) -> bool:
    """The same floats, zeros' signs included (a NaN's sign bit is not a value)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    num = ~np.isnan(a)
    return (a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
            and np.array_equal(np.signbit(a[num]), np.signbit(b[num])))


@pytest.fixture(scope="module")
def state():
    return PosteriorState(load_forward_model("tilelink/pointmass"))


def test_response_spline_same_floats(state):
    m = state.fm.members[0]
    sub = state.omega[state.rows[0]]
    rng = np.random.default_rng(0)
    fs = [*rng.uniform(9.0, 41.0, 40), *m.atlas.f_hz[[0, 7, -1]], 5.0, 60.0]  # nodes and extrapolation
    for amp in (3.0, 12.0):
        at = inf.member_response(m, amp, sub, state.alpha)[0]
        for f in fs:
            a, b = both(lambda at=at, f=f: at(f))
            assert all(same(x, y) for x, y in zip(a, b, strict=True)), (amp, f)
    nan = both(lambda: at(float("nan")))
    assert all(np.isnan(x).all() for x in nan[0] + nan[1])


def test_likelihood_same_floats(state):
    m = state.fm.members[0]
    at = inf.member_response(m, 3.0, state.omega[state.rows[0]], state.alpha)[0]
    rng = np.random.default_rng(1)
    for f in rng.uniform(10.0, 40.0, 12):
        mu, s, p = at(f)
        for y, e in ((rng.uniform(-50, 400), rng.uniform(0, 20)), (0.0, 0.0)):
            for unstable in (False, True):
                args = (mu, s, p, y, e, unstable, m.sigma_model, m.atlas.n_repeats)
                a, b = both(lambda args=args: inf.probe_log_likelihood(*args))
                assert same(a, b), (f, y, e, unstable)
    # edge values: zero variance, signed zeros, NaN, p at 0 and 1
    mu = np.array([[0.0, -0.0, np.nan, 5.0], [1e300, -1e-300, 3.0, 2.0]])
    s = np.array([[0.0, -0.0, 1.0, np.nan], [0.0, 2.0, np.inf, 1.0]])
    p = np.array([[0.0, -0.0, 1.0, np.nan], [0.5, 1.0, 0.0, 0.25]])
    for unstable in (False, True):
        a, b = both(lambda un=unstable: inf.probe_log_likelihood(mu, s, p, 0.0, 0.0, un, 0.0, 4))
        assert same(a, b)


def test_spline_point_same_floats():
    atlas = load_atlas("tilelink", "pointmass")
    rng = np.random.default_rng(2)
    pts = [(rng.uniform(9, 41), amp, rng.uniform(atlas.omega_n[0] * 0.9, atlas.omega_n[-1] * 1.1),
            rng.uniform(atlas.alpha[0] - 0.1, atlas.alpha[-1] + 0.1)) for amp in (3.0, 12.0) for _ in range(300)]
    pts += [(float(f), 12.0, float(w), float(a)) for f in atlas.f_hz[::6] for w in atlas.omega_n[::4] for a in
            atlas.alpha]
    for pt in pts:
        a, b = both(lambda pt=pt: atlas.predict_point(*pt))
        assert same(a, b), pt


def random_table(rng, n: int, repeats: bool = False) -> ProbeTable:
    f = rng.uniform(10.0, 40.0, n)
    amp = rng.choice([3.0, 12.0], n)
    y = rng.uniform(-20.0, 300.0, n)
    e = rng.uniform(0.1, 10.0, n)
    un = rng.random(n) < 0.4
    if repeats and n > 3:
        f[1], amp[1], y[1], e[1], un[1] = f[0], amp[0], y[0], e[0], un[0]
    return ProbeTable.from_arrays(f, amp, y, e, un)


@pytest.mark.parametrize("n", [1, 3, 9, 17, 140])
def test_estimate_and_check_same_floats(n):
    fm = load_forward_model("tilelink/pointmass")
    rng = np.random.default_rng(n)
    for rep in range(3):
        table = random_table(rng, n, repeats=rep == 1)

        def run(table=table):
            st = PosteriorState(fm)
            st.add_table(table)
            est = st.estimate()
            return est.to_dict(), st.log_likes[0].copy(), est.check

        (d0, ll0, c0), (d1, ll1, c1) = both(run)
        assert same(ll0, ll1)
        assert repr(d0) == repr(d1)
        assert c0 == c1  # statistic, p-value, worst probe


def test_replicate_count_sums_as_numpy():
    """The check's replicate sums: numpy's pairwise order for every row length up to 128 (a plain left-to-right
    sum differs from n = 8 on)."""
    from plate_env.core import grid_kernels as g

    rng = np.random.default_rng(3)
    for n in range(1, 129):
        u = rng.random((500, n))
        t_part = rng.standard_t(4.0, (500, n)) ** 2 * 10 ** rng.uniform(-3, 3, (500, n))
        p = rng.uniform(0.05, 0.95, n)
        flag_s, flag_u = -np.log(1.0 - p), -np.log(p)
        t_rep = np.where(u >= p, t_part + flag_s, flag_u).sum(-1)
        for t_obs in np.quantile(t_rep, [0.1, 0.5, 0.9]).tolist() + [float(t_rep[7])]:
            assert g.replicates_at_least(u, t_part, p, flag_s, flag_u, t_obs) == np.count_nonzero(t_rep >= t_obs)


def test_kernels_load_at_the_warm_episode_end(monkeypatch):
    monkeypatch.delenv("PLATE_ENV_JIT", raising=False)
    monkeypatch.setitem(jit._state, "module", None)
    monkeypatch.setitem(jit._state, "episodes", 0)
    assert all(jit.kernels() is None for _ in range(1000))  # requests alone never load them
    for _ in range(jit.WARM_EPISODES - 1):
        jit.episode_ended()
        assert jit.kernels() is None
    jit.episode_ended()
    assert jit.kernels() is not None
    jit.force(False)
    assert jit.kernels() is None
    jit.force(None)
    monkeypatch.setitem(jit._state, "module", None)
    monkeypatch.setitem(jit._state, "episodes", 0)
    monkeypatch.setenv("PLATE_ENV_JIT", "0")
    for _ in range(jit.WARM_EPISODES + 5):
        jit.episode_ended()
    assert jit.kernels() is None
    monkeypatch.setenv("PLATE_ENV_JIT", "1")
    assert jit.kernels() is not None


def test_env_episode_ends_load_the_kernels():
    """An env process switches to the kernels at its WARM_EPISODES-th episode end (in a fresh interpreter)."""
    import os
    import subprocess
    import sys

    code = ("import sys, numpy as np\n"
            "from plate_env.env import PlateRotationEnv\n"
            "from plate_env.core import jit\n"
            "env = PlateRotationEnv(physics='atlas')\n"
            "seen = []\n"
            "for seed in range(jit.WARM_EPISODES):\n"
            "    env.reset(seed=seed)\n"
            "    env.step(env.encode_action(20.0, 3.0, 1.0))\n"
            "    seen.append('numba' in sys.modules)\n"
            "    env.step(env.encode_action(stop=True))\n"
            "print(seen, jit.kernels() is not None)")
    env = {k: v for k, v in os.environ.items() if k != "PLATE_ENV_JIT"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout
    assert out.strip() == "[False, False, False, False, False] True"


def test_env_episodes_same_with_and_without_kernels():
    from plate_env.env import PlateRotationEnv

    def run():
        env = PlateRotationEnv(physics="atlas")
        rng = np.random.default_rng(4)
        out = []
        for seed in range(6):
            env.reset(seed=seed)
            done = False
            while not done:
                a = rng.uniform(-1, 1, 4)
                a[3] = 1.0 if rng.random() < 0.15 else -1.0
                obs, r, done, _, info = env.step(a)
                info.pop("wall_s", None)
                out.append((obs.tobytes(), r, repr(info)))
        return out

    a, b = both(run)
    assert a == b
    assert not math.isnan(a[-1][1])
