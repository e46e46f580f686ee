"""Checks of user-given values, shared by the environment, the command line and the backends.

Each returns the value in its plain Python type or raises ``ValueError`` naming the value and the allowed range,
so a bad value is refused before any work is done. Booleans are not numbers here (``True`` is no probe budget),
and NaN or infinity is never inside a range.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from numbers import Integral, Real


def interval(lo: float, hi: float, open_lo: bool = False, open_hi: bool = False, unit: str = "") -> str:
    """``"[lo, hi] unit"`` with round brackets on open ends, e.g. ``"(0, 45] deg"``."""
    fmt = "d" if isinstance(lo, int) and isinstance(hi, int) else "g"
    text = f"{'(' if open_lo else '['}{lo:{fmt}}, {hi:{fmt}}{')' if open_hi else ']'}"
    return f"{text} {unit}" if unit else text


def real(name: str, value: object, lo: float = -math.inf, hi: float = math.inf, *, open_lo: bool = False,
         open_hi: bool = False, unit: str = "") -> float:
    """``value`` as a float if it is a finite real number within [lo, hi] (open ends as asked)."""
    allowed = interval(lo, hi, open_lo, open_hi, unit) if math.isfinite(lo) or math.isfinite(hi) else (
        f"a finite number{' of ' + unit if unit else ''}")
    if isinstance(value, bool) or not isinstance(value, Real):
        raise ValueError(f"{name} = {value!r} is not a number; allowed: {allowed}")
    x = float(value)
    inside = math.isfinite(x) and (lo < x if open_lo else lo <= x) and (x < hi if open_hi else x <= hi)
    if not inside:
        raise ValueError(f"{name} = {value!r} is outside the allowed range {allowed}")
    return x


def integer(name: str, value: object, lo: int, hi: int) -> int:
    """``value`` as an int if it is an integer (not a bool, not a float) within [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise ValueError(f"{name} = {value!r} is not an integer; allowed: {interval(lo, hi)}")
    if not lo <= int(value) <= hi:
        raise ValueError(f"{name} = {value!r} is outside the allowed range {interval(lo, hi)}")
    return int(value)


def pair(name: str, value: object, lo: float, hi: float, unit: str = "") -> tuple[float, float]:
    """``value`` as an increasing pair (a, b) of finite numbers with lo <= a < b <= hi."""
    message = f"{name} = {value!r} must be an increasing pair within {interval(lo, hi, unit=unit)}"
    try:
        a, b = value  # type: ignore[misc]
    except (TypeError, ValueError):
        raise ValueError(message) from None
    try:
        a, b = real(name, a, lo, hi), real(name, b, lo, hi)
    except ValueError:
        raise ValueError(message) from None
    if not a < b:
        raise ValueError(message)
    return a, b


def one_of(name: str, value: object, choices: Iterable) -> object:
    """``value`` if it is one of ``choices``."""
    choices = tuple(choices)
    if not any(value == c and type(value) is type(c) for c in choices):
        raise ValueError(f"{name} = {value!r}: choose one of {choices}")
    return value


def known_keys(name: str, mapping: object, allowed: Iterable[str]) -> dict:
    """``mapping`` as a dict if it is a mapping whose keys are all in ``allowed`` (a misspelt key is refused)."""
    allowed = tuple(allowed)
    if mapping is None:
        return {}
    if not isinstance(mapping, Mapping):
        raise ValueError(f"{name} = {mapping!r} must be a dict with keys from {allowed}")
    unknown = [k for k in mapping if k not in allowed]
    if unknown:
        raise ValueError(f"{name}: unknown key(s) {unknown}; allowed: {allowed}")
    return dict(mapping)
