"""Specs, plate motion and unit handling."""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.core.motion import plate_state
from plate_env.core.units import parse_omega_n


def test_import_is_light():
    import subprocess
    import sys

    # gymnasium is not among them: importing the package registers its ids, as panda-gym does (~80 ms; issue 35)
    heavy = ('numba', 'pybullet', 'torch', 'matplotlib', 'scipy.stats', 'scipy.signal', 'scipy.spatial')
    for module in ("plate_env", "plate_env.cli"):  # the command line's start-up too (plate-env fit needs none)
        code = f"import sys, {module}; print([m for m in {heavy!r} if m in sys.modules])"
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
        assert out.strip() == "[]", module


@pytest.mark.parametrize("first", ["plate_env", "gymnasium"])
def test_env_ids_are_registered_whichever_is_imported_first(first):
    """``import plate_env`` registers the ids (importing gymnasium, as panda-gym does), whatever was imported first,
    and gym.make finds them."""
    import subprocess
    import sys

    second = "gymnasium" if first == "plate_env" else "plate_env"
    code = (f"import sys, {first}; before = 'gymnasium' in sys.modules; import {second}; import gymnasium as gym\n"
            "env = gym.make('PlateRotation-v0', physics='atlas'); env.reset(seed=0)\n"
            "print(before, 'plate_env/PlateRotation-v0' in gym.registry, type(env.unwrapped).__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "True", "PlateRotationEnv"]


@pytest.mark.parametrize("text, value", [("10pi", 10 * math.pi), ("3.5π", 3.5 * math.pi), ("pi", math.pi),
                                         ("31.4", 31.4), ("1e1pi", 10 * math.pi)])
def test_parse_omega_n(text, value):
    assert parse_omega_n(text) == pytest.approx(value)


@pytest.mark.parametrize("text", ["abc", "-3pi", "nan", "0", "inf"])
def test_parse_omega_n_rejects(text):
    with pytest.raises(ValueError, match="omega_n"):
        parse_omega_n(text)


def test_object_spec_friction_and_presets():
    cheese = pe.preset("cheese")
    assert cheese.omega_n == pytest.approx(10 * math.pi)
    assert cheese.mu_s == pytest.approx(math.tan(math.radians(36.9)))
    assert cheese.mu_k == pytest.approx(0.53 * cheese.mu_s)
    assert pe.preset("dumpling").mass == pytest.approx(6.9e-3)
    assert pe.preset("cheese_lead").mass == pytest.approx(39.5e-3)
    with pytest.raises(ValueError, match="unknown object preset"):
        pe.preset("pizza")


@pytest.mark.parametrize("field, value", [("omega_n", float("nan")), ("alpha", -0.1), ("mass", 0.0)])
def test_object_spec_rejects_bad_values(field, value):
    with pytest.raises(ValueError, match="outside the allowed range"):
        pe.ObjectSpec(**{field: value})


def test_object_prior_is_seeded_log_uniform_and_draws_two_numbers_an_object():
    prior = pe.core.objects.ObjectPrior()
    objs = prior.sample(400, seed=3)
    assert objs == prior.sample(400, seed=3) and objs != prior.sample(400, seed=4)
    w = np.array([o[0] for o in objs]) / math.pi
    a = np.degrees([o[1] for o in objs])
    assert 3.5 <= w.min() and w.max() <= 33.0 and 30.0 <= a.min() and a.max() <= 60.0
    mid = 0.5 * (math.log(3.5) + math.log(33.0))  # log-uniform: log omega_n centred on the middle of the range
    assert abs(np.mean(np.log(w)) - mid) < 0.1 and abs(np.mean(a) - 45.0) < 1.5
    rng, ref = np.random.default_rng(5), np.random.default_rng(5)
    prior.draw(rng)
    ref.uniform(size=2)
    assert rng.uniform() == ref.uniform()  # exactly two draws: callers' later random streams do not shift


def test_plate_motion_rejects_nan():
    with pytest.raises(ValueError, match="f_p"):
        pe.PlateMotion(freq_hz=float("nan"), amp_rad=0.05)


def test_plate_motion_follows_eqs_1_2_and_ramp_is_smooth():
    m = pe.PlateMotion.from_paper(f_p_hz=25, a_p_deg=3, b_p_mm=3, ramp_s=0.2)
    # after the ramp: Theta = -A sin(2 pi f t), X = B sin(2 pi f t)
    t = 0.31
    th, th_dot, x, x_dot = m.state(t)
    w = 2 * math.pi * 25
    assert th == pytest.approx(-math.radians(3) * math.sin(w * t))
    assert x == pytest.approx(3e-3 * math.sin(w * t))
    assert th_dot == pytest.approx(-math.radians(3) * w * math.cos(w * t))
    # starts at rest, and the analytic velocities are the derivatives of the positions everywhere
    assert m.state(0.0) == pytest.approx((0.0, 0.0, 0.0, 0.0))
    ts = np.linspace(0.0, 0.4, 4001)
    states = np.array([plate_state(tt, 25.0, math.radians(3), 3e-3, 0.2) for tt in ts])
    num = np.gradient(states[:, [0, 2]], ts, axis=0)
    assert np.allclose(num[1:-1], states[1:-1][:, [1, 3]], atol=2e-3 * np.abs(states[:, [1, 3]]).max())


def test_probe_spec_windows():
    spec = pe.ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(25, 3), settle_s=0.5, measure_s=1.0)
    assert spec.n_periods == 25
    assert spec.duration_s == pytest.approx(0.2 + 0.5 + 1.0)
    assert pe.ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(1, 3), measure_s=0.1).n_periods == 2
    with pytest.raises(ValueError, match="measure_s"):
        pe.ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(25, 3), measure_s=float("nan"))


def test_unknown_physics_is_named():
    with pytest.raises(ValueError, match="unknown physics 'bullet'"):
        pe.make_physics("bullet")


def test_first_atlas_step_imports_neither_the_posterior_nor_numba():
    """gym.make + reset + a first atlas probe load only the env, the physics and the atlas: the posterior's modules
    come with the first episode end, numba with the compiled kernels (plate_env.core.jit), and plate_env.identify's
    public names still resolve."""
    import subprocess
    import sys

    code = ("import sys, gymnasium as gym, plate_env\n"
            "env = gym.make('PlateRotation-v0', physics='atlas'); env.reset(seed=0)\n"
            "env.step(env.unwrapped.encode_action(20.0, 3.0, 1.0))\n"
            "mods = ('plate_env.identify.api', 'plate_env.identify.inference', 'plate_env.identify.forward', 'numba')\n"
            "print([m for m in mods if m in sys.modules])\n"
            "_, _, term, _, info = env.step(env.unwrapped.encode_action(stop=True))\n"
            "print(term, 'omega_n_rad_s' in info['estimate'], 'numba' in sys.modules)\n"
            "import plate_env.identify as idf\n"
            "print(idf.METHODS, callable(idf.identify), 'plate_env.identify.api' in sys.modules)")
    env = {k: v for k, v in __import__("os").environ.items() if k != "PLATE_ENV_JIT"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env=env).stdout.splitlines()
    assert out == ["[]", "True True False", "('atlas', 'lorentz') True True"]
