"""A simple adaptive heuristic: a coarse sweep, then refine around the highest stable probe of the first hump."""

from __future__ import annotations

import numpy as np

from plate_env.core import checks
from plate_env.core.probe_table import ProbeTable
from plate_env.core.setup import FREQ_RANGE_HZ, MAX_PROBES_RANGE
from plate_env.env.protocol import Agent, Probe, probe_options
from plate_env.identify.fitting import first_hump_mask


class CoarseToFineAgent(Agent):
    """``n_coarse`` probes over the band, then ``n_fine`` probes spread +-``width_hz`` around the first-hump peak,
    halving the spread each round; estimate by ``method``."""

    name = "coarse_to_fine"

    def __init__(self, n_coarse: int = 6, n_fine: int = 6, width_hz: float = 4.0, a_p_deg: float = 3.0,
                 measure_s: float = 1.0, method: str = "atlas") -> None:
        self.n_coarse = checks.integer("n_coarse", n_coarse, *MAX_PROBES_RANGE)
        self.n_fine = checks.integer("n_fine", n_fine, 0, MAX_PROBES_RANGE[1])
        self.width_hz = checks.real("width_hz", width_hz, 0.0, FREQ_RANGE_HZ[1], open_lo=True, unit="Hz")
        self.a_p_deg, self.measure_s = probe_options(a_p_deg, measure_s)
        self.method = method

    def next_probe(self, history: ProbeTable, obs=None) -> Probe | None:
        k = len(history)
        if k >= min(self.n_coarse + self.n_fine, self.context.max_probes):
            return None
        lo, hi = self.context.f_band_hz
        if k < self.n_coarse:
            return Probe(float(np.linspace(lo, hi, self.n_coarse)[k]), self.a_p_deg, self.measure_s)
        mask = first_hump_mask(history.f_p_hz, history.omega_b_deg_s, ~history.unstable)
        if mask.any():
            peak = float(history.f_p_hz[mask][np.argmax(history.omega_b_deg_s[mask])])
        else:
            peak = (lo + hi) / 2
        j = k - self.n_coarse
        width = self.width_hz / 2 ** (j // 2)
        f = peak + (width if j % 2 == 0 else -width) * (0.5 + 0.5 * ((j // 2) % 2))
        while np.any(np.isclose(history.f_p_hz, f, atol=0.05)):
            f += 0.25
        return Probe(float(np.clip(f, lo, hi)), self.a_p_deg, self.measure_s)
