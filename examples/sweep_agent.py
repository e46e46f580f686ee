"""A third-party probing agent in ~20 lines (README, "Write your own agent"): sweep up the band at 3 deg and stop
once the response has passed its peak (the last two probes below the highest; an unstable probe counts as 0)."""

import numpy as np

from plate_env.env.protocol import Agent, Probe


class SweepAgent(Agent):
    name = "sweep_until_past_peak"
    method = "atlas"  # estimate with the forward model's posterior

    def next_probe(self, history, obs=None):
        lo, hi = self.context.f_band_hz
        n = len(history)
        w = np.where(history.unstable, 0.0, history.omega_b_deg_s)  # past the hump, probes slip or fall
        past_peak = n >= 4 and w[-2:].max() < w.max()
        if n >= self.context.max_probes or past_peak or lo + 2.0 * n > hi:
            return None  # stop: the episode's probes are turned into an estimate
        return Probe(f_p_hz=lo + 2.0 * n, a_p_deg=3.0, measure_s=1.0)
