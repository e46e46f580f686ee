"""Determinism across processes: the guarantee the README states, tested exactly.

Same inputs and seed give bit-identical numbers (full yaw and centre traces of both tile-link models, of the
point-mass kernel v2 and of ``rigid_fast``, singles and batches, and a seeded tile-link env episode's observations,
rewards and infos without ``wall_s``) in

* a process that compiles the numba kernels (empty ``NUMBA_CACHE_DIR``) and one that loads them from the disk cache;
* this process and another one.

Before the fix (``plate_env/physics/tilelink/kernels.py``'s docstring) a compiling process bound the kernels' calls
to other copies of the helpers than a cache-loading one: the point-mass yaw trace differed from the first
millisecond and a seeded env episode in 2 of 14 records; the rigid kernel's omega_B by up to 0.4 %.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()


def measure() -> dict:
    """Digests of the traces and a seeded env episode (run in this process or, via ``_run``, in another)."""
    import plate_env as pe
    from plate_env.core.probe import ProbeSpec
    from plate_env.env.rotation import PlateRotationEnv

    def digest(results) -> str:
        return hashlib.sha256(b"".join(r.trace.yaw.tobytes() + r.trace.centre_u.tobytes() + r.trace.centre_v.tobytes()
                                       for r in results)).hexdigest()

    out: dict = {}
    objs = (pe.ObjectSpec.from_paper(10.0, 36.9), pe.ObjectSpec.from_paper(23.0, 45.0))
    for model, settle_s, measure_s in (("pointmass", 0.5, 1.0), ("pointmass_v2", 0.5, 1.0), ("rigid", 0.1, 0.3),
                                       ("rigid_fast", 0.1, 0.2)):
        specs = [ProbeSpec(o, pe.PlateMotion.from_paper(f, 3.0, 3.0), settle_s=settle_s, measure_s=measure_s,
                           record_trace=True) for o in objs for f in (18.0, 22.0)]
        physics = (pe.make_physics("tilelink", model="pointmass", kernel="v2") if model == "pointmass_v2"
                   else pe.make_physics("tilelink", model=model))
        singles = [physics.run([s])[0] for s in specs]
        out[f"{model}_single"] = digest(singles)
        out[f"{model}_batch"] = digest(physics.run(specs))
        out[f"{model}_omega_b"] = [r.omega_b_deg_s for r in singles]
    env = PlateRotationEnv(physics="tilelink", max_probes=6)
    obs, info = env.reset(seed=7)
    episode = [repr((obs.tolist(), info))]
    rng = np.random.default_rng(0)
    for _ in range(6):
        action = rng.uniform(-1, 1, 4).astype(np.float32)
        action[3] = -1.0
        obs, reward, terminated, truncated, info = env.step(action)
        info.pop("wall_s", None)
        episode.append(repr((obs.tolist(), reward, terminated, truncated, info)))
    env.close()
    out["env_episode"] = episode
    return out


def _run(cache_dir: str | None = None) -> dict:
    """``measure()`` in a fresh interpreter, with ``NUMBA_CACHE_DIR`` set to ``cache_dir`` if given."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    code = (f"import json, runpy; print(json.dumps(runpy.run_path({str(HERE)!r})['measure']()))")
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def test_fresh_compile_and_disk_cache_give_identical_numbers(tmp_path):
    compiled = _run(str(tmp_path))  # empty cache: compiles every kernel and writes the cache
    assert any(tmp_path.rglob("*.nbi")), "numba wrote no cache, so the second run would not test it"
    reloaded = _run(str(tmp_path))  # loads the cached code
    for key in compiled:
        assert compiled[key] == reloaded[key], key
    for model in ("pointmass", "pointmass_v2", "rigid", "rigid_fast"):
        assert compiled[f"{model}_single"] == compiled[f"{model}_batch"]  # a batch repeats its single runs


def test_same_numbers_in_this_process_and_another():
    here = measure()
    there = _run()  # the default cache, as this process uses it
    for key in here:
        assert here[key] == there[key], key
