"""Comparing what a build recomputes on this machine with what was committed from the machine that made it.

The last bits of a float depend on the CPU (numpy's vectorised exp/log and BLAS kernels differ between AVX2 and
AVX-512), and fits and simulations carry such differences into later digits. Text, structure, counts and flags are
machine-independent and compared exactly; numbers within :data:`CROSS_CPU_RTOL` (``tests/cross_cpu.py`` asserts it,
``experiments/cross_cpu.py`` measures it).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

#: Relative tolerance for numbers rebuilt on another CPU. Measured on an AMD EPYC (AVX-512) against files committed
#: from the shipping machine (experiments/results/cross_cpu.md): largest relative difference 2.5e-7, in the 12-deg
#: Eq. (10) line (R^2 0.08: an ill-conditioned fit of Lorentzian f0s that converge to ~1e-8); 5e-13 in the
#: forward-model registry; 9e-16 in a probe's omega_B. 40x the largest: any change to a fit, a grid or a probe
#: moves these numbers by far more.
CROSS_CPU_RTOL = 1e-5


def differences(a, b, path: str = "") -> Iterator[tuple[str, object, object, float]]:
    """``(path, a value, b value, relative difference)`` for every number of two JSON-like values; a difference in
    structure, a string, a bool or None yields ``inf``. The relative difference of two numbers is
    ``|a - b| / max(|a|, |b|)`` (0 when both are 0)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            yield path, sorted(a), sorted(b), math.inf
            return
        for k in a:
            yield from differences(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            yield path, len(a), len(b), math.inf
            return
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            yield from differences(x, y, f"{path}[{i}]")
    elif (isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool)
          and not isinstance(b, bool)):
        if a == b or (math.isnan(a) and math.isnan(b)):
            yield path, a, b, 0.0
        else:
            yield path, a, b, abs(a - b) / max(abs(a), abs(b))
    else:
        yield path, a, b, 0.0 if a == b else math.inf


__all__: Sequence[str] = ("CROSS_CPU_RTOL", "differences")
