"""Resumable cached sweeps: the cache key names every backend setting that changes a result."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pytest

import plate_env as pe
from plate_env.physics.base import ProbeResult, ProbeSpec
from plate_env.physics.tilelink.params import DEFAULT_RECORD_INTERVAL_S, P_RECEVERY
from plate_env.sweeps import backend_tag, load_cache, run_cached


class FakeTileLink:
    """Stands in for a tile-link backend: records what it is asked to run; omega_B tells the record interval."""

    name = "tilelink"
    model = "pointmass"
    dt = 2e-4

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
