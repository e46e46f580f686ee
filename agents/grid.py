"""The paper's method: a uniform f_p sweep at one plate amplitude, then the Lorentzian fit and Eq. (10)."""

from __future__ import annotations

import numpy as np

from plate_env.core import checks
from plate_env.core.probe_table import ProbeTable
from plate_env.core.setup import MAX_PROBES_RANGE
from plate_env.env.protocol import Agent, Probe, probe_options


class GridAgent(Agent):
    """``n`` probes evenly over the band at ``a_p_deg``, each with a ``measure_s`` window; estimate by ``method``."""

    name = "grid"

    def __init__(self, n: int = 16, a_p_deg: float = 3.0, measure_s: float = 1.0, method: str = "lorentz") -> None:
        self.n = checks.integer("n", n, *MAX_PROBES_RANGE)  # more points than any episode's probes: never swept
        self.a_p_deg, self.measure_s = probe_options(a_p_deg, measure_s)
        self.method = method

    def next_probe(self, history: ProbeTable, obs=None) -> Probe | None:
        k = len(history)
        if k >= min(self.n, self.context.max_probes):
            return None
        freqs = np.linspace(*self.context.f_band_hz, self.n)
        return Probe(float(freqs[k]), self.a_p_deg, self.measure_s)
