"""Comparing what a build recomputes on this machine with what was committed from the machine that made it.

The last bits of a float depend on the CPU (numpy's vectorised exp/log and BLAS kernels differ between AVX2 and
AVX-512), and fits and simulations carry such differences into later digits. Text, structure, counts and flags are
machine-independent and compared exactly; numbers within ``CROSS_CPU_RTOL`` (both from
:mod:`plate_env.build.compare`).
"""

from __future__ import annotations

from plate_env.build.compare import CROSS_CPU_RTOL, differences


def assert_close(a, b, rtol: float = CROSS_CPU_RTOL) -> float:
    """Assert ``a`` and ``b`` equal in structure and text and their numbers within ``rtol``; returns the largest
    relative difference found (for the record)."""
    worst = max((d for d in differences(a, b)), key=lambda d: d[3], default=("", None, None, 0.0))
    assert worst[3] <= rtol, f"{worst[0]}: {worst[1]!r} vs {worst[2]!r} (relative {worst[3]:.3g} > {rtol:g})"
    return worst[3]
