"""Bad input and faults (issue 16): each defect found by the audit of main as a test that failed there.

Refusals name the value and the allowed range before any work is done; nothing is clamped or ignored silently.
Fast: atlas physics, or tile-link runs that are refused before they start.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.atlas import load_atlas
from plate_env.env import PlateRotationEnv
from plate_env.physics.base import ProbeSpec

PROBE = np.array([0.0, -1.0, 0.0, -1.0], np.float32)


def spec(obj=None, f_p_hz=25.0, a_p_deg=3.0, b_p_mm=3.0, **kw) -> ProbeSpec:
    return ProbeSpec(obj or pe.preset("cheese"), pe.PlateMotion.from_paper(f_p_hz, a_p_deg, b_p_mm), **kw)


# ------------------------------------------------------------------------- defect 6: atlas physics off its grid
@pytest.mark.parametrize("probe, names", [
    (spec(f_p_hz=200.0), ("f_p = 200 Hz", "10-40 Hz")),
    (spec(obj=pe.ObjectSpec(omega_n=1e-9)), ("omega_n", "1.4-40 pi rad/s")),
    (spec(obj=pe.ObjectSpec(alpha=math.radians(10.0))), ("alpha = 10 deg", "28-60 deg")),
    (spec(b_p_mm=0.0), ("B_p = 0 mm", "B_p = 3 mm")),
    (spec(b_p_mm=5.0), ("B_p = 5 mm", "B_p = 3 mm")),
    (spec(obj=pe.preset("cheese_lead")), ("mass = 39.5 g", "mass = 13.6 g")),
    (spec(obj=pe.ObjectSpec(diameter=0.1)), ("diameter = 100 mm", "diameter = 80 mm")),
    (spec(a_p_deg=5.0), ("A_p = 5 deg", "3, 12 deg")),
])
def test_atlas_physics_refuses_probes_outside_its_atlas(probe, names):
    physics = pe.make_physics("atlas")
    good = spec()
    with pytest.raises(ValueError) as err:
        physics.run([good, probe])  # the whole call is refused, before any probe is answered
    for text in names:
        assert text in str(err.value)


def test_atlas_physics_answers_inside_and_flips_sign_with_b_p():
    physics = pe.make_physics("atlas")
    pos, neg = physics.run([spec(f_p_hz=24.0), spec(f_p_hz=24.0, b_p_mm=-3.0)])
    assert pos.omega_b_deg_s > 100 and neg.omega_b_deg_s < -100


def test_atlas_domain_follows_its_provenance():
    atlas = load_atlas("tilelink", "pointmass")
    assert atlas.fixed() == pytest.approx({"b_p": 0.003, "mass": 0.0136, "diameter": 0.08})  # shipped values
    heavy = pe.atlas.Atlas(**{**{f: getattr(atlas, f) for f in ("physics", "model", "f_hz", "a_p_deg", "omega_n",
                                                                  "alpha", "mean", "spread", "p_unstable",
                                                                  "n_repeats")},
                              "provenance": {**atlas.provenance, "mass_g": 39.5, "b_p_mm": 2.0}})
    assert heavy.outside(mass=0.0395, b_p=-0.002) == {}
    assert set(heavy.outside(mass=0.0136, b_p=0.003)) == {"mass", "b_p"}
    assert set(atlas.outside(f_p_hz=10.0, omega_n=40 * math.pi, alpha=math.radians(28), a_p_deg=-12.0)) == set()


# ---------------------------------------------------------------- defects 6 and 8: env options and reset options
@pytest.mark.parametrize("kwargs, name", [
    (dict(camera_fps=0), "camera_fps"),
    (dict(camera_fps=float("nan")), "camera_fps"),
    (dict(camera_fps=-30), "camera_fps"),
    (dict(angle_noise_deg=-1), "angle_noise_deg"),
    (dict(cost_per_sim_s=float("nan")), "cost_per_sim_s"),
    (dict(error_cap=0.0), "error_cap"),
    (dict(no_estimate_penalty=float("inf")), "no_estimate_penalty"),
    (dict(amplitudes_deg=(5.0,)), "amplitudes_deg"),  # the atlas holds 3 and 12 deg only
    (dict(amplitudes_deg=(3.0, 3.0)), "amplitudes_deg"),
    (dict(amplitudes_deg=()), "amplitudes_deg"),
    (dict(b_p_mm=1e6), "b_p_mm"),
    (dict(b_p_mm=2.0), "b_p_mm"),  # the atlas was built at 3 mm
    (dict(settle_s=-1), "settle_s"),
    (dict(max_probes=True), "max_probes"),
    (dict(max_probes=2.0), "max_probes"),
    (dict(max_sim_s=float("nan")), "max_sim_s"),
    (dict(mass_variation=0.1), "mass_variation"),  # the atlas describes one mass
    (dict(f_band_hz=(5.0, 40.0)), "f_band_hz"),
    (dict(omega_n_range_pi=(1.0, 33.0)), "omega_n_range_pi"),
    (dict(render_mode="human2"), "render_mode"),
    (dict(physics_options=3), "physics_options"),
])
def test_env_options_refused_at_construction_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        PlateRotationEnv(physics="atlas", **kwargs)


def test_env_options_the_live_physics_can_honour_are_accepted():
    env = PlateRotationEnv(physics="tilelink", mass_variation=0.2, b_p_mm=2.0, amplitudes_deg=(5.0,), max_probes=2)
    env.reset(seed=0)
    env.close()


@pytest.mark.parametrize("options, name", [
    ({"omega": 5.0}, "omega"),  # misspelt: was silently ignored (a random object instead)
    ({"omega_n": "10pi"}, "omega_n"),
    ({"alpha": float("nan")}, "alpha"),
    ({"mass": -1.0}, "mass"),
    ({"mass": 0.0395}, "mass"),  # atlas: built at 13.6 g
    ({"omega_n": 1e-9}, "omega_n"),  # atlas: off its grid
    ([("omega_n", 30.0)], "reset options"),
])
def test_reset_options_checked_naming_them(options, name):
    env = PlateRotationEnv(physics="atlas")
    with pytest.raises(ValueError, match=name):
        env.reset(seed=0, options=options)


def test_reset_options_fix_the_object_without_changing_the_seeded_draws():
    env = PlateRotationEnv(physics="atlas", max_probes=3)
    _, info = env.reset(seed=4, options={"omega_n": 30.0, "alpha": 0.7})
    assert (info["omega_n_true"], info["alpha_true"]) == (30.0, 0.7)
    a = env.step(PROBE)[0]
    env.reset(seed=4, options={"omega_n": 30.0, "alpha": 0.7, "mass": 0.0136})
    assert np.array_equal(a, env.step(PROBE)[0])


@pytest.mark.parametrize("action", [
    np.array([0.0, -1.0, 0.0, -1.0], np.complex128),
    np.array([True, False, False, False]),
    [True, False, False, False],
    np.array(["0", "0", "0", "-1"]),
])
def test_complex_bool_and_text_actions_refused(action):
    env = PlateRotationEnv(physics="atlas")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="real numbers"):
        env.step(action)
    assert len(env.table()) == 0


def test_step_and_reset_after_close_raise():
    env = PlateRotationEnv(physics="atlas")
    env.reset(seed=0)
    env.step(PROBE)
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.step(PROBE)
    with pytest.raises(RuntimeError, match="closed"):
        env.reset(seed=1)
