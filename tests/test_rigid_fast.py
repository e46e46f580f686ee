"""model="rigid_fast" (issue 26): registry, determinism, refusals, instability reporting, and agreement with the
converged rigid-limit reference (experiments/results/rigid_reference.json) on cheap probes."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import pytest

import plate_env as pe
from plate_env.core.probe import ProbeRefused, ProbeSpec
from plate_env.physics.tilelink import rigid
from plate_env.physics.tilelink.params import DEFAULT_DT

REFERENCE = Path(__file__).resolve().parents[1] / "experiments" / "results" / "rigid_reference.json"


def _probe(f_hz: float, settle: float = 0.1, measure: float = 0.1, omega_pi: float = 10.0) -> ProbeSpec:
    return ProbeSpec(obj=pe.ObjectSpec.from_paper(omega_pi, 36.9), motion=pe.PlateMotion.from_paper(f_hz, 3.0, 3.0),
                     settle_s=settle, measure_s=measure, initial_yaw=0.3, initial_offset=(1e-4, -2e-4))


def test_rigid_fast_is_registered_with_its_own_step_and_config():
    physics = pe.make_physics("tilelink", model="rigid_fast")
    assert physics.dt == DEFAULT_DT["rigid_fast"]
    assert physics.rigid_config == rigid.RIGID_FAST_CONFIG
    assert physics.rigid_config.iterations == 1
    assert physics.rigid_config.omega_rigid == rigid.RIGID_LIMIT_CONFIG.omega_rigid
    res = physics.run([_probe(22.0)])[0]
    assert not res.unstable and math.isfinite(res.omega_b_deg_s) and res.omega_b_deg_s > 0


def test_same_inputs_give_identical_results_single_and_batch():
    physics = pe.make_physics("tilelink", model="rigid_fast")
    specs = [_probe(20.0), _probe(24.0, omega_pi=33.0)]
    a = physics.run(specs)
    b = physics.run(specs)
    single = [physics.run([s])[0] for s in specs]
    for x, y, z in zip(a, b, single, strict=True):
        assert x.omega_b_deg_s == y.omega_b_deg_s == z.omega_b_deg_s
        assert x.unstable == y.unstable == z.unstable


def test_absurd_steps_are_refused_before_any_work():
    with pytest.raises(ValueError, match="dt"):
        pe.make_physics("tilelink", model="rigid_fast", dt=0.0)
    physics = pe.make_physics("tilelink", model="rigid_fast", dt=1e-9)
    with pytest.raises(ProbeRefused, match="time steps"):
        physics.run([_probe(20.0)])
    with pytest.warns(UserWarning, match="rigid_fast"):
        pe.make_physics("tilelink", model="rigid_fast", dt=1e-4)


def test_a_step_too_large_for_one_sweep_is_reported_unstable_with_a_reason_not_nan():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        physics = pe.make_physics("tilelink", model="rigid_fast", dt=1e-4)
    res = physics.run([_probe(22.0)])[0]
    assert res.unstable and res.reason
    assert math.isfinite(res.omega_b_deg_s) and math.isfinite(res.stderr_deg_s)


@pytest.mark.parametrize("key", ["10pi_36.9deg_14Hz", "10pi_36.9deg_18Hz"])
def test_agrees_with_the_converged_rigid_limit_on_cheap_probes(key):
    """Within the issue's median tolerance (2 %) on two stable low-frequency probes of the reference."""
    row = next(r for r in json.loads(REFERENCE.read_text())["probes"] if r["key"] == key)
    assert not row["unstable"]
    spec = ProbeSpec(obj=pe.ObjectSpec.from_paper(row["omega_n_pi"], row["alpha_deg"]),
                     motion=pe.PlateMotion.from_paper(row["f_p_hz"], row["a_p_deg"], row["b_p_mm"]),
                     settle_s=row["settle_s"], measure_s=row["measure_s"], initial_yaw=row["initial_yaw_rad"],
                     initial_offset=tuple(row["initial_offset_m"]))
    res = pe.make_physics("tilelink", model="rigid_fast").run([spec])[0]
    assert not res.unstable
    assert res.omega_b_deg_s == pytest.approx(row["omega_b_deg_s"], rel=0.02)


def test_a_nuisance_draw_keeps_the_models_own_solver_values():
    from plate_env.physics.nuisance import Nuisance

    for model in ("rigid", "rigid_limit", "rigid_fast"):
        cfg = Nuisance(k_inplane=600.0).tilelink_options(model)["rigid_config"]
        assert cfg.k_inplane == 600.0
        assert (cfg.omega_rigid, cfg.iterations) == (rigid.MODEL_CONFIGS[model].omega_rigid,
                                                    rigid.MODEL_CONFIGS[model].iterations)
