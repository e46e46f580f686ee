"""Sequential Bayesian experimental design on the atlas posterior over (omega_n, alpha).

After every probe the grid posterior (plate_env.inference) is updated. The next probe (f_p, A_p and its
measurement window) maximises the expected reduction of the posterior variance of log omega_n per simulated
second it costs (ramp + settle + window). The expectation is a preposterior Monte Carlo over the atlas's
predictive distribution: with the predictive instability probability the probe ends unstable (and the posterior
is reweighted by p), otherwise omega_B ~ mu + sqrt(s^2 + sigma_model^2 + se(T)^2) * Normal(0, 1) at objects
drawn from the posterior (scored with the same Student-t likelihood as the posterior), where se(T) = SE_1S /
sqrt(T / 1 s) is the window's own measurement error. The agent stops when the
posterior standard deviation of omega_n falls below ``target_rel`` of its mean, or the budget is spent. A probe
is never repeated at the same (f_p, A_p): the atlas's model error there is shared, so the posterior would
count it twice and grow overconfident (measured: repeats drove a 17pi estimate 3.5 sigma off).

Windows. The atlas describes 1 s windows; shorter ones scatter more between placements than their own standard
error says (10 Hz, 12 deg, 21pi: 84-109 deg/s over four placements with 0.3 s windows, 146-153 with 1 s), so
the default windows are 1 and 2 s. Over 16 seeded live tile-link objects, 0.25-2 s windows gave a median error of
7.9 % (1-sigma coverage 19 %), 1-2 s windows 3.9 % (coverage 50 %).
"""

from __future__ import annotations

import math

import numpy as np

from agents.base import Agent, Probe
from plate_env import checks
from plate_env.atlas import load_atlas
from plate_env.inference import (
    P_MIN,
    SIGMA_MODEL,
    grid_response,
    log_student,
    posterior_grid,
    probe_log_likelihood,
)
from plate_env.probes import ProbeTable

#: Typical standard error of a probe's omega_B over a 1 s window, deg/s (tile-link probes: 0.5-2 deg/s).
SE_1S = 2.0


class BayesAgent(Agent):
    """Adaptive probing by expected variance reduction of log omega_n per simulated second."""

    name = "bayes"
    method = "atlas"

    def __init__(self, target_rel: float = 0.03, windows_s: tuple[float, ...] = (1.0, 2.0),
                 f_step_hz: float = 0.5, n_samples: int = 12, n_omega: int = 81, n_alpha: int = 16,
                 min_probes: int = 3, sigma_model: float = SIGMA_MODEL, atlas=None) -> None:
        self.target_rel = checks.real("target_rel", target_rel, 0.0, 1.0, open_hi=True)
        self.windows_s = windows_s
        self.f_step_hz = f_step_hz
        self.n_samples = n_samples
        self.n_omega = n_omega
        self.n_alpha = n_alpha
        self.min_probes = min_probes
        self.sigma_model = sigma_model
        self._atlas = atlas

    def reset(self, context, rng) -> None:
        super().reset(context, rng)
        self.atlas = self._atlas if self._atlas is not None else load_atlas(context.physics, context.model)
        self.omega, self.alpha = posterior_grid(self.atlas, self.n_omega, self.n_alpha)
        self.log_w = np.log(self.omega)[:, None]
        lo, hi = context.f_band_hz
        self.freqs = np.arange(lo, hi + 1e-9, self.f_step_hz)
        self.amps = [a for a in context.amplitudes_deg if np.any(np.isclose(self.atlas.a_p_deg, a))]
        if not self.amps:
            raise ValueError(f"none of the env's amplitudes {context.amplitudes_deg} is in the atlas")
        m_lo, m_hi = context.measure_range_s
        self.windows = [w for w in self.windows_s if m_lo <= w <= m_hi] or [m_lo]
        # predictive tables for every candidate (amplitude, frequency): (n_f, n_omega, n_alpha)
        self.tables = {}
        for a in self.amps:
            at = grid_response(self.atlas, a, self.n_omega, self.n_alpha)
            mus, ss, ps = zip(*(at(f) for f in self.freqs), strict=True)
            self.tables[a] = (np.array(mus), np.array(ss), np.clip(np.array(ps), P_MIN, 1 - P_MIN))
        self.logp = np.zeros((self.n_omega, self.n_alpha))
        self._seen = 0

    # ----------------------------------------------------------------- posterior
    def _update(self, history: ProbeTable) -> None:
        for k in range(self._seen, len(history)):
            amp = float(history.a_p_deg[k])
            at = grid_response(self.atlas, amp, self.n_omega, self.n_alpha)
            mu, s, p = at(history.f_p_hz[k])
            self.logp += probe_log_likelihood(mu, s, p, history.omega_b_deg_s[k], history.stderr_deg_s[k],
                                              bool(history.unstable[k]), self.sigma_model)
        self._seen = len(history)

    def posterior(self) -> np.ndarray:
        p = np.exp(self.logp - self.logp.max())
        return p / p.sum()

    def relative_std(self) -> float:
        p = self.posterior().sum(1)
        mean = float(p @ self.omega)
        return math.sqrt(max(float(p @ (self.omega - mean) ** 2), 0.0)) / mean

    @staticmethod
    def _var_log(prob: np.ndarray, log_w: np.ndarray) -> np.ndarray:
        """Posterior variance of log omega_n for a stack of unnormalised posteriors (..., n_omega, n_alpha)."""
        z = prob.sum(axis=(-2, -1))
        m1 = (prob * log_w).sum(axis=(-2, -1)) / z
        m2 = (prob * log_w ** 2).sum(axis=(-2, -1)) / z
        return np.maximum(m2 - m1 ** 2, 0.0)

    # ----------------------------------------------------------------- design
    def next_probe(self, history: ProbeTable, obs=None) -> Probe | None:
        self._update(history)
        ctx = self.context
        n = len(history)
        if n >= ctx.max_probes:
            return None
        if n >= self.min_probes and self.relative_std() <= self.target_rel:
            return None
        post = self.posterior()
        v0 = float(self._var_log(post, self.log_w))
        flat = post.ravel()
        best, best_u = None, -np.inf
        for a in self.amps:
            mus, ss, ps = self.tables[a]
            done = history.f_p_hz[np.isclose(history.a_p_deg, a)]
            # objects drawn from the posterior, shared by all candidates of this amplitude (common random numbers)
            cells = self.rng.choice(flat.size, size=self.n_samples, p=flat)
            z = self.rng.normal(size=self.n_samples)
            for i_f in range(len(self.freqs)):
                if np.any(np.abs(done - self.freqs[i_f]) < 0.5 * self.f_step_hz):
                    continue  # the physics is deterministic up to placement: a repeat adds little, and its
                    # model error is not independent of the first one's
                mu, s, p = mus[i_f], ss[i_f], ps[i_f]
                p_un = float((post * p).sum())
                var_un = float(self._var_log(post * p, self.log_w))
                mu_c, s_c = mu.ravel()[cells], s.ravel()[cells]
                for window in self.windows:
                    se2 = SE_1S ** 2 / window
                    var = s ** 2 + se2 + self.sigma_model ** 2
                    y = mu_c + z * np.sqrt(s_c ** 2 + se2 + self.sigma_model ** 2)
                    like = (1 - p)[None] * np.exp(log_student(y[:, None, None] - mu[None], var[None]))
                    var_st = float(np.mean(self._var_log(post[None] * like, self.log_w[None])))
                    expected = p_un * var_un + (1 - p_un) * var_st
                    cost = ctx.overhead_s + window * (1 - p_un) + 0.5 * window * p_un
                    u = (v0 - expected) / cost
                    if u > best_u:
                        best_u, best = u, Probe(float(self.freqs[i_f]), a, window)
        return best
