"""Atlas grids named by data (plate_env.atlas_grid): validation, probe order and placement, a resumable build."""

from __future__ import annotations

import json

import numpy as np
import pytest

from plate_env.build.atlas_grid import AtlasGrid, grid_probes, result_arrays, run_grid
from plate_env.run.executor import BackendSpec
from plate_env.run.sweeps import load_cache

SMALL = {"f_p_hz": "14:18:2", "a_p_deg": [3], "omega_n_pi": [10, 17], "alpha_deg": [40], "settle_s": 0.2,
         "measure_s": 0.3}


def test_a_grid_file_is_read_and_checked(tmp_path):
    path = tmp_path / "grid.json"
    path.write_text(json.dumps(SMALL))
    grid = AtlasGrid.from_json(path)
    assert grid.f_hz == (14.0, 16.0, 18.0) and grid.omega_n_pi == (10.0, 17.0) and grid.settle_s == 0.2
    assert AtlasGrid.from_dict(grid.to_dict()) == grid
    for bad, match in (({**SMALL, "f_p_hz": [18, 14]}, "increase"), ({**SMALL, "alpha_deg": []}, "at least one"),
                       ({**SMALL, "omega_n_pi": [-1, 2]}, "positive"), ({**SMALL, "f_p_hz": "10:x:1"}, "start:stop"),
                       ({**SMALL, "amps": [3]}, "unknown keys"), ({"f_p_hz": [10]}, "missing keys"),
                       ({**SMALL, "measure_s": 1e4}, "measure_s")):
        with pytest.raises(ValueError, match=match):
            AtlasGrid.from_dict(bad)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not JSON"):
        AtlasGrid.from_json(path)


def test_grid_probes_order_and_seeded_placement():
    grid = AtlasGrid.from_dict(SMALL)
    order, specs = grid_probes(grid, 2, np.random.default_rng(3))
    assert order == list(np.ndindex(grid.shape(2))) and len(specs) == 12
    assert len({s.initial_yaw for s in specs}) == 12  # every probe placed afresh
    _, again = grid_probes(grid, 2, np.random.default_rng(3))
    assert again == specs
    order_s, centred = grid_probes(grid, 1, np.random.default_rng(3), placed=False, sweeps=True)
    assert all(s.initial_yaw == 0.0 and s.initial_offset == (0.0, 0.0) for s in centred)
    # sweeps: one object's frequencies ascending, then the next object
    assert [ix[0] for ix in order_s[:3]] == [0, 1, 2] and order_s[3][2] == 1


def test_run_grid_fills_the_result_array_and_resumes(tmp_path):
    grid = AtlasGrid.from_dict(SMALL)
    cache = tmp_path / "atlas.jsonl"
    res = run_grid(BackendSpec.of("tilelink"), grid, 1, seed=0, cache=cache, chunk=4, progress=False)
    omega, se, un = result_arrays(res)
    assert omega.shape == grid.shape(1) and len(load_cache(cache)) == 6
    for idx in np.ndindex(res.shape):
        r = res[idx]
        assert r.spec.motion.freq_hz == grid.f_hz[idx[0]]
        assert np.isclose(r.spec.obj.omega_n, grid.omega_n_pi[idx[2]] * np.pi)
    assert not un.any() and (se > 0).all()
    assert (omega[2] > omega[0]).all()  # the rising edge: 18 Hz turns faster than 14 Hz
    again = run_grid(BackendSpec.of("tilelink"), grid, 1, seed=0, cache=cache, chunk=4, progress=False,
                     executor="pool:2")  # everything cached: no worker needed
    assert np.array_equal(result_arrays(again)[0], omega)
