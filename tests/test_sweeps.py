"""Resumable cached sweeps: the cache key names every backend setting that changes a result; an interrupted sweep
resumes where it stopped."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pytest

import plate_env as pe
from plate_env.core.probe import ProbeResult, ProbeSpec
from plate_env.physics.interface import PhysicsBackend
from plate_env.physics.tilelink.params import DEFAULT_RECORD_INTERVAL_S, P_RECEVERY
from plate_env.run.sweeps import backend_tag, load_cache, run_cached


class FakeTileLink(PhysicsBackend):
    """Stands in for a tile-link backend: records what it is asked to run; omega_B tells the record interval."""

    name = "tilelink"
    model = "pointmass"
    dt = 2e-4
    SETTINGS = ("model", "dt", "record_interval_s")

    def __init__(self, record_interval_s: float) -> None:
        self.record_interval_s = record_interval_s
        self.simulated: list[ProbeSpec] = []

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        self.simulated.extend(probes)
        return [ProbeResult(spec=s, omega_b_deg_s=1e3 * self.record_interval_s, stderr_deg_s=0.0, unstable=False,
                            reason=None, sim_s=s.duration_s, wall_s=0.0, periods_measured=s.n_periods)
                for s in probes]

    def close(self) -> None:
        pass


def _specs() -> list[ProbeSpec]:
    return [ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(f, 3.0)) for f in (20.0, 25.0)]


def test_record_interval_is_part_of_the_cache_key(tmp_path: Path):
    cache = tmp_path / "sweep.jsonl"
    default = FakeTileLink(DEFAULT_RECORD_INTERVAL_S)
    first = run_cached(default, _specs(), cache, progress=False)
    assert len(default.simulated) == 2 and len(load_cache(cache)) == 2
    sparse = FakeTileLink(5e-3)  # same backend, model and dt: only the record interval differs
    again = run_cached(sparse, _specs(), cache, progress=False)
    assert len(sparse.simulated) == 2  # not served from the other interval's results
    assert [r.omega_b_deg_s for r in again] == [5.0, 5.0] and [r.omega_b_deg_s for r in first] == [1.0, 1.0]
    repeat = FakeTileLink(DEFAULT_RECORD_INTERVAL_S)
    run_cached(repeat, _specs(), cache, progress=False)
    assert repeat.simulated == []


def test_tilelink_record_interval_is_a_backend_option():
    dt = 2e-4
    default = pe.make_physics("tilelink", dt=dt)
    sparse = pe.make_physics("tilelink", dt=dt, record_interval_s=5e-3)
    spec = _specs()[0]
    assert default._param_vector(spec)[P_RECEVERY] == round(DEFAULT_RECORD_INTERVAL_S / dt)
    assert sparse._param_vector(spec)[P_RECEVERY] == 25
    assert backend_tag(default) != backend_tag(sparse) and "record_interval_s=0.005" in backend_tag(sparse)
    for bad in (0.0, -1e-3, float("nan"), 1.0):
        with pytest.raises(ValueError, match="record_interval_s"):
            pe.make_physics("tilelink", record_interval_s=bad)


class InterruptingPhysics(PhysicsBackend):
    """Wraps a backend, counts the probes it simulates and raises KeyboardInterrupt on call ``interrupt_at``."""

    def __init__(self, inner, interrupt_at: int | None = None) -> None:
        self.inner = inner
        self.name = "wrapped-" + inner.name
        self.interrupt_at = interrupt_at
        self.calls = 0
        self.simulated: list[ProbeSpec] = []

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        self.calls += 1
        if self.interrupt_at is not None and self.calls == self.interrupt_at:
            raise KeyboardInterrupt
        self.simulated.extend(probes)
        return self.inner.run(probes)

    def close(self) -> None:
        self.inner.close()


def test_interrupted_sweep_resumes(tmp_path: Path):
    specs = [ProbeSpec(pe.preset("cheese"), pe.PlateMotion.from_paper(float(f), 3.0)) for f in range(10, 30)]
    cache = tmp_path / "sweep.jsonl"
    first = InterruptingPhysics(pe.make_physics("atlas"), interrupt_at=3)
    with pytest.raises(KeyboardInterrupt):
        run_cached(first, specs, cache, chunk=4, progress=False)
    assert len(first.simulated) == 8 and len(load_cache(cache)) == 8  # two chunks kept
    second = InterruptingPhysics(pe.make_physics("atlas"))
    resumed = run_cached(second, specs, cache, chunk=4, progress=False)
    assert len(second.simulated) == 12
    assert {s.motion.freq_hz for s in second.simulated} == {float(f) for f in range(18, 30)}
    direct = pe.make_physics("atlas").run(specs)
    assert [r.omega_b_deg_s for r in resumed] == [r.omega_b_deg_s for r in direct]
    third = InterruptingPhysics(pe.make_physics("atlas"))
    run_cached(third, specs, cache, chunk=4, progress=False)
    assert third.simulated == []


def test_a_probe_keeps_its_key_across_the_last_bit_a_cpu_changes_and_old_full_repr_keys_still_hit(tmp_path):
    """A prior-drawn omega_n can differ in its last bit between CPUs (numpy's vectorised exp): the same probe must
    keep its cache key; a cache written with the old full-``repr`` keys is still read (experiments/results/
    cross_cpu.md); two probes that differ beyond the rounding keep different keys."""
    import dataclasses
    import json
    import math

    from plate_env.run.sweeps import canonical_key, spec_key

    here = ProbeSpec(obj=pe.ObjectSpec.from_paper(20.612924744036566, 45.0),
                     motion=pe.PlateMotion.from_paper(18.0, 3.0), initial_yaw=0.3, initial_offset=(1e-4, -2e-4))
    other_cpu = dataclasses.replace(here, obj=dataclasses.replace(here.obj, omega_n=math.nextafter(here.obj.omega_n,
                                                                                                   math.inf)))
    assert spec_key("t", here) == spec_key("t", other_cpu)
    apart = dataclasses.replace(here, obj=dataclasses.replace(here.obj, omega_n=here.obj.omega_n * (1 + 1e-9)))
    assert spec_key("t", apart) != spec_key("t", here)
    o, m = here.obj, here.motion
    old = "t|" + ",".join(repr(float(x)) for x in (o.omega_n, o.alpha, o.mass, o.diameter, o.beta, m.freq_hz,
                                                    m.amp_rad, m.b_p, m.ramp_s, here.settle_s, here.measure_s,
                                                    here.initial_yaw, *here.initial_offset))
    assert old != spec_key("t", here) and canonical_key(old) == spec_key("t", here)
    cache = tmp_path / "c.jsonl"
    cache.write_text(json.dumps({"key": old, "omega_b_deg_s": 1.0, "stderr_deg_s": 0.1, "unstable": False,
                                 "reason": "", "sim_s": 1.0, "wall_s": 1.0, "periods_measured": 3}) + "\n")
    assert spec_key("t", other_cpu) in load_cache(cache)
