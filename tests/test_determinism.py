"""The same probe in a process that compiles the kernels and in one that reloads them from numba's disk cache.

Measured: the point-mass kernel repeats bit for bit. The rigid-tile kernel's freshly compiled code and its cached
code differ in the last bits (with its fastmath flags ~5e-12 relative after 0.5 s; without any fastmath still
1 ulp), which the disc's sensitive dynamics can grow to ~0.4 % of omega_B over a 1.6 s probe (448.07 against
450.01 deg/s, 10pi at 22 Hz): the run right after a compile does not repeat later runs exactly.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

SCRIPT = """
import plate_env as pe
from plate_env.physics.base import ProbeSpec
spec = ProbeSpec(obj=pe.ObjectSpec.from_paper(10.0, 36.9), motion=pe.PlateMotion.from_paper(22.0, 3.0, 3.0),
                 settle_s=0.1, measure_s=0.2)
print(" ".join(repr(pe.make_physics("tilelink", model=m).run([spec])[0].omega_b_deg_s)
               for m in ("pointmass", "rigid")))
"""


def _run(cache_dir: str) -> list[float]:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return [float(x) for x in done.stdout.split()]


def test_fresh_compile_and_disk_cache(tmp_path):
    compiled = _run(str(tmp_path))  # empty cache: compiles and writes the cache
    assert any(tmp_path.rglob("*.nbi")), "numba wrote no cache, so the second run would not test it"
    reloaded = _run(str(tmp_path))  # loads the cached code
    assert compiled[0] == reloaded[0]  # point mass: bit for bit
    assert compiled[1] == pytest.approx(reloaded[1], rel=1e-9, abs=0.0)  # rigid: rounding only, over 0.5 s
