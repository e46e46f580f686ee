"""Sequential Bayesian experimental design on a forward model's posterior over (omega_n, alpha).

After every probe the posterior of the forward model (:mod:`~plate_env.identify.forward`: the physics' atlas, its
measured errors, the coherent discrepancy) is updated. The next probe (f_p, A_p and its measurement window) maximises
the expected reduction of the posterior variance of log omega_n per simulated second it costs (ramp + settle +
window). The expectation is a preposterior Monte Carlo over the forward model's own predictive distribution: with
the predictive instability probability the probe ends unstable (and each member's posterior is reweighted by its
p), otherwise omega_B ~ mu + sqrt(s^2 + sigma_model^2 + se(T)^2) * Normal(0, 1) at objects drawn from the
posterior, scored with the same likelihood as the posterior (:func:`plate_env.identify.inference.probe_log_likelihood`),
where se(T) = SE_1S / sqrt(T / 1 s) is the window's own measurement error. Its utility is thus what the forward
model can predict: an outcome the atlas gives as a coin flip (a smoothed instability share near 1/2, a wide
spread) carries little expected information, so such probes are not chased. The discrepancy adds the same
variance to every candidate's outcome, so it does not move the choice; it does stop the agent once the posterior
can get no narrower. Its likelihood is blurred along log omega_n beyond the members' own blur
(:data:`DESIGN_BLUR`), so its estimate is the forward model's posterior made robust to its own choice of probes.
The agent stops when the half-width of the 68 % interval falls below ``target_rel`` of
omega_n, or the budget is spent. A probe is never repeated at the same (f_p, A_p): the atlas's model error there is
shared, so the posterior would count it twice.

Windows: the atlas describes 1 s windows; shorter ones scatter more between placements than their own standard
error says, so the default windows are 1 and 2 s.
"""

from __future__ import annotations

import dataclasses
import json
import math
from importlib import resources

import numpy as np

from plate_env.core import checks
from plate_env.core.probe_table import ProbeTable
from plate_env.env.protocol import Agent, Probe
from plate_env.identify.forward import ForwardModel, load_forward_model
from plate_env.identify.inference import blurred, log_student, member_domain, member_response, smoothed_p
from plate_env.identify.posterior_state import PosteriorState


def _load_design_discrepancy() -> dict[str, tuple[float, float]]:
    """``{forward model: (scale, nu)}`` from the shipped ``models/bayes_design_discrepancy.json``."""
    data = json.loads((resources.files("plate_env_agents") / "models" / "bayes_design_discrepancy.json").read_text())
    return {name: (float(v["scale"]), float(v["nu"])) for name, v in data["design_discrepancy"].items()}


#: The agent's own blur (sd of log omega_n), added in quadrature to each member's: an adaptive design puts its
#: probes where the atlas predicts the sharpest change (instability edges, the rising flank), exactly where its
#: interpolation between omega_n nodes errs most (without it the 68 % intervals held the truth in 0.57 of 40 live
#: episodes, with it 0.68).
DESIGN_BLUR = 0.04
#: The coherent discrepancy of the agent's estimates (scale of log omega_n, Student-t degrees of freedom), per
#: forward model it was calibrated on: it replaces that model's own discrepancy (fitted on full sweeps) in the
#: episode's estimate, because probes chosen adaptively on the model, many close in frequency and sharing its
#: error, and read through the agent's blur, err differently from a sweep. A fitted value, so it lives in data:
#: ``models/bayes_design_discrepancy.json`` (its provenance inside), written by ``plate-env build
#: design-discrepancy`` from the fit of experiments/forward_models.py within (plate_env.build.design_discrepancy).
#: Another forward model keeps its own discrepancy.
DESIGN_DISCREPANCY: dict[str, tuple[float, float]] = _load_design_discrepancy()
#: Typical standard error of a probe's omega_B over a 1 s window, deg/s (tile-link probes: 0.5-2 deg/s).
SE_1S = 2.0


class BayesAgent(Agent):
    """Adaptive probing by expected variance reduction of log omega_n per simulated second."""

    name = "bayes"
    method = "atlas"

    def __init__(self, target_rel: float = 0.03, windows_s: tuple[float, ...] = (1.0, 2.0),
                 f_step_hz: float = 0.5, n_samples: int = 12, n_omega: int = 81, n_alpha: int = 16,
                 min_probes: int = 3, forward: ForwardModel | None = None, blur: float = DESIGN_BLUR,
                 design_discrepancy: tuple[float, float] | None = None) -> None:
        self.target_rel = checks.real("target_rel", target_rel, 0.0, 1.0, open_hi=True)
        self.blur = checks.real("blur", blur, 0.0, 1.0)
        if design_discrepancy is not None:
            design_discrepancy = (checks.real("design_discrepancy scale", design_discrepancy[0], 0.0, 1.0),
                                  checks.real("design_discrepancy nu", design_discrepancy[1], 0.5, math.inf))
        self.design_discrepancy = design_discrepancy
        self.windows_s = windows_s
        self.f_step_hz = f_step_hz
        self.n_samples = n_samples
        self.n_omega = n_omega
        self.n_alpha = n_alpha
        self.min_probes = min_probes
        self._forward = forward

    def reset(self, context, rng) -> None:
        super().reset(context, rng)
        fm = self._forward
        if fm is None:
            fm = load_forward_model(f"{context.physics}/{context.model}", context.known)
        self.fm = fm
        self.omega, self.alpha = fm.grid(self.n_omega, self.n_alpha)
        self.log_w = np.log(self.omega)[:, None]
        lo, hi = context.f_band_hz
        self.freqs = np.arange(lo, hi + 1e-9, self.f_step_hz)
        m_lo, m_hi = context.measure_range_s
        self.windows = [w for w in self.windows_s if m_lo <= w <= m_hi] or [m_lo]
        # candidates: (amplitude, frequency) inside at least one member's atlas; per member and amplitude its
        # predictive tables over the candidate frequencies
        tables = {a: [self._table(m, a) for m in fm.members] for a in context.amplitudes_deg}
        self.tables = {a: per for a, per in tables.items() if any(t is not None for t in per)}
        self.amps = list(self.tables)
        if not self.amps:
            raise ValueError(f"none of the env's amplitudes {context.amplitudes_deg} is in forward model {fm.name!r}")
        # the design posterior: on the agent's grid, every member's likelihood on the whole grid, blurred by the
        # agent's blur too, members compared on their own probes
        self.state = PosteriorState(fm, grid=(self.omega, self.alpha),
                                    blurs=[math.hypot(m.blur, self.blur) for m in fm.members],
                                    member_rows_only=False, compare_on_common=False)
        self.inside = self.state.inside
        self.blur_steps = self.state.blur_steps
        self._pu: dict = {}

    def _table(self, member, a_p_deg: float):
        """A member's predictive over the candidate frequencies at one amplitude: (covered (n_f,), mean, spread,
        smoothed p (n_f, n_omega, n_alpha)), or None when it covers none of them."""
        covered = np.array([member_domain(member, float(f), a_p_deg) is None for f in self.freqs])
        if not covered.any():
            return None
        at = member_response(member, a_p_deg, self.omega, self.alpha)[0]
        shape = (len(self.freqs), len(self.omega), self.n_alpha)
        mus, ss, ps = np.zeros(shape), np.ones(shape), np.full(shape, 0.5)
        for i in np.flatnonzero(covered):
            mus[i], ss[i], ps[i] = at(float(self.freqs[i]))
        return covered, mus, ss, smoothed_p(ps, member.atlas.n_repeats)

    # ----------------------------------------------------------------- posterior
    def _update(self, history: ProbeTable) -> None:
        self.state.add_table(history, start=self.state.n_probes)

    def posterior(self):
        """What the probes say: the forward model's posterior on the agent's grid, without the discrepancies no
        probe can reduce (a :class:`plate_env.identify.estimate.Posterior`); the stopping rule reads it."""
        return self.state.posterior(discrepancy=False)

    def fingerprint(self) -> str:
        """The shipped design discrepancy (data, not code: names it in benchmark records beside the source)."""
        return json.dumps(sorted(DESIGN_DISCREPANCY.items()))

    def design_eps(self) -> tuple[float, float]:
        """(scale, nu) of the estimate's coherent discrepancy: ``design_discrepancy`` if given, else
        :data:`DESIGN_DISCREPANCY` for this forward model, else the forward model's own."""
        fm = self.fm
        return self.design_discrepancy or DESIGN_DISCREPANCY.get(fm.name, (fm.sigma_eps, fm.eps_nu))

    def estimate_model(self) -> ForwardModel:
        """The forward model the episode's estimate is computed with: the agent's blur added to every member's (in
        quadrature) and the coherent discrepancy of :meth:`design_eps`; an offset between models is kept."""
        fm = self.fm
        sigma, nu = self.design_eps()
        return dataclasses.replace(
            fm, name=f"{fm.name} (adaptive design)",
            members=tuple(dataclasses.replace(m, blur=math.hypot(m.blur, self.blur)) for m in fm.members),
            sigma_eps=sigma, eps_nu=nu)

    def relative_std(self) -> float:
        """Half the 68 % interval of omega_n over its median, from the probes' information alone."""
        m = self.posterior().omega()
        return m.stderr / m.value

    def _member_posts(self) -> tuple[np.ndarray, np.ndarray]:
        """Unsmoothed per-member posteriors (K, n_omega, n_alpha), each normalised, and the members' weights."""
        return self.state.member_posteriors()

    def _pooled_var(self, posts: np.ndarray, wts: np.ndarray) -> np.ndarray:
        """Variance of log omega_n of mixtures: ``posts`` (..., K, n_omega, n_alpha) unnormalised per member,
        ``wts`` (..., K) member weights (before the members' own masses)."""
        z = posts.sum(axis=(-2, -1))
        wz = wts * z
        tot = wz.sum(-1)
        m1 = (wts[..., None, None] * posts * self.log_w).sum(axis=(-3, -2, -1)) / tot
        m2 = (wts[..., None, None] * posts * self.log_w ** 2).sum(axis=(-3, -2, -1)) / tot
        return np.maximum(m2 - m1 ** 2, 0.0)

    # ----------------------------------------------------------------- design
    def _unstable_at(self, a: float, i_f: int) -> tuple[np.ndarray, np.ndarray]:
        """Per member, the blurred instability probability of the candidate (amplitude ``a``, frequency index
        ``i_f``) on the grid (ones where a member does not cover it), and which members cover it; computed once
        per episode and candidate (it depends on neither the probes nor the draws)."""
        key = (a, i_f)
        if key not in self._pu:
            per = self.tables[a]
            self._pu[key] = (
                np.stack([np.exp(blurred(np.log(t[3][i_f]), self.blur_steps[j])) if (t is not None and t[0][i_f])
                          else np.ones((len(self.omega), self.n_alpha)) for j, t in enumerate(per)]),
                np.array([t is not None and bool(t[0][i_f]) for t in per]))
        return self._pu[key]

    def next_probe(self, history: ProbeTable, obs=None) -> Probe | None:
        self._update(history)
        ctx = self.context
        n = len(history)
        if n >= ctx.max_probes:
            return None
        if n >= self.min_probes and self.relative_std() <= self.target_rel:
            return None
        posts, wts = self._member_posts()
        k_mem = len(self.fm.members)
        v0 = float(self._pooled_var(posts, wts))
        best, best_u = None, -np.inf
        for a in self.amps:
            per = self.tables[a]
            done = history.f_p_hz[np.isclose(history.a_p_deg, a)]
            # objects (member, cell) drawn from the posterior, shared by this amplitude's candidates
            members = self.rng.choice(k_mem, size=self.n_samples, p=wts)
            cells = np.array([self.rng.choice(posts[j].size, p=posts[j].ravel()) for j in members])
            z = self.rng.normal(size=self.n_samples)
            for i_f in range(len(self.freqs)):
                if np.any(np.abs(done - self.freqs[i_f]) < 0.5 * self.f_step_hz):
                    continue  # a repeat's model error is not independent of the first one's
                if all(t is None or not t[0][i_f] for t in per):
                    continue
                # per member: p at this candidate (members that do not cover it learn nothing from it)
                pu, covers = self._unstable_at(a, i_f)
                p_un = float(np.sum(wts * np.where(covers, (posts * pu).sum(axis=(1, 2)), 0.0)))
                post_un = np.where(covers[:, None, None], posts * pu, posts)
                var_un = float(self._pooled_var(post_un, wts)) if p_un > 0 else v0
                for window in self.windows:
                    se2 = SE_1S ** 2 / window
                    y = np.empty(self.n_samples)
                    for s_i, (j, c) in enumerate(zip(members, cells, strict=True)):
                        t = per[j]
                        if t is None or not t[0][i_f]:
                            y[s_i] = np.nan
                            continue
                        mu_c = t[1][i_f].ravel()[c]
                        s_c = t[2][i_f].ravel()[c]
                        y[s_i] = mu_c + z[s_i] * math.sqrt(s_c ** 2 + se2 + self.fm.members[j].sigma_model ** 2)
                    valid = ~np.isnan(y)
                    if not valid.any():
                        continue
                    yv = y[valid][:, None, None]
                    like = np.ones((int(valid.sum()), k_mem, len(self.omega), self.n_alpha))
                    for j, t in enumerate(per):
                        if t is not None and t[0][i_f]:
                            mu, s, p = t[1][i_f], t[2][i_f], t[3][i_f]
                            var = s ** 2 + se2 + self.fm.members[j].sigma_model ** 2
                            like[:, j] = np.exp(blurred(np.log1p(-p)[None] + log_student(yv - mu[None], var[None]),
                                                        self.blur_steps[j]))
                    var_st = float(np.mean(self._pooled_var(posts[None] * like, wts[None])))
                    expected = p_un * var_un + (1 - p_un) * var_st
                    cost = ctx.overhead_s + window * (1 - p_un) + 0.5 * window * p_un
                    u = (v0 - expected) / cost
                    if u > best_u:
                        best_u, best = u, Probe(float(self.freqs[i_f]), a, window)
        return best
