"""Unit conversions at the edges (CLI, CSV, plots).

Everything inside the package is SI: metres, kilograms, seconds, radians, rad/s; frequencies in Hz.
Degrees, millimetres and the paper's "units of pi rad/s" appear only at the edges, with the unit in the name.
"""

from __future__ import annotations

import math
import re

_PI_RE = re.compile(r"^\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)?\s*\*?\s*(pi|π)\s*$", re.IGNORECASE)


def parse_omega_n(text: str | float) -> float:
    """Parse an angular frequency in rad/s; accepts the paper's notation ``"10pi"``, ``"10π"``, ``"pi"``.

    >>> round(parse_omega_n("10pi"), 6) == round(10 * math.pi, 6)
    True
    """
    if isinstance(text, (int, float)):
        value = float(text)
    else:
        match = _PI_RE.match(text)
        if match:
            value = float(match.group(1) or 1.0) * math.pi
        else:
            try:
                value = float(text)
            except ValueError:
                raise ValueError(
                    f"omega_n {text!r} is not a number of rad/s nor of the form '10pi' (units of pi rad/s)"
                ) from None
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"omega_n must be a finite positive angular frequency in rad/s, got {text!r}")
    return value


def format_omega_pi(omega_rad_s: float) -> str:
    """Format rad/s as the paper writes it, e.g. ``10.0pi``."""
    return f"{omega_rad_s / math.pi:.4g}pi"
