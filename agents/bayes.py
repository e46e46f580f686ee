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
from plate_env.identify.inference import NU, blurred, member_domain, member_response, smoothed_p
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
    """Adaptive probing by expected variance reduction of log omega_n per simulated second. ``forward``: the forward
    model it designs on and estimates through, a :class:`~plate_env.identify.forward.ForwardModel` or a shipped
    model's name (``"lab"``, ``"tilelink/pointmass"``: conditioned on each episode's known inputs); None: the
    episode physics' own."""

    name = "bayes"
    method = "atlas"

    def __init__(self, target_rel: float = 0.03, windows_s: tuple[float, ...] = (1.0, 2.0),
                 f_step_hz: float = 0.5, n_samples: int = 12, n_omega: int = 81, n_alpha: int = 16,
                 min_probes: int = 3, forward: ForwardModel | str | None = None, blur: float = DESIGN_BLUR,
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
        if isinstance(forward, str):
            from plate_env_agents import check_forward_name

            self.forward = check_forward_name(forward)  # named in the agent's fingerprint (benchmark records)
        self._forward = forward

    def reset(self, context, rng) -> None:
        super().reset(context, rng)
        fm = self._forward
        if fm is None or isinstance(fm, str):  # a name: the shipped model, conditioned on the episode's inputs
            fm = load_forward_model(fm or f"{context.physics}/{context.model}", context.known)
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
        self._blur_matrices = [self._blur_matrix(j) for j in range(len(fm.members))]
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
    def _blur_matrix(self, j: int) -> np.ndarray:
        """Member ``j``'s blur along log omega_n as a matrix ``G`` (n_omega, n_omega): ``G @ x`` is
        :func:`~plate_env.identify.inference.blurred`'s Gaussian filter of ``x`` along omega (``mode="nearest"``)."""
        from scipy.ndimage import gaussian_filter1d

        if self.blur_steps[j] <= 0:
            return np.eye(len(self.omega))
        return gaussian_filter1d(np.eye(len(self.omega)), self.blur_steps[j], axis=0, mode="nearest", truncate=4.0)

    def _design_tables(self, a: float):
        """Per amplitude, once per episode: each member's candidate tables flattened over the grid cells (covered
        (n_f,), mean, spread, smoothed p, spread^2, 1 - p (n_f, n_cells)) or None, and the blurred instability
        probability of every candidate (K, n_f, n_cells; it depends on neither the probes nor the draws) with which
        members cover it (K, n_f)."""
        key = ("design", a)
        if key not in self._pu:
            per = self.tables[a]
            n_f, n_c = len(self.freqs), len(self.omega) * self.n_alpha
            flat = [None if t is None else (t[0], t[1].reshape(n_f, n_c), t[2].reshape(n_f, n_c),
                                            t[3].reshape(n_f, n_c), t[2].reshape(n_f, n_c) ** 2,
                                            1.0 - t[3].reshape(n_f, n_c)) for t in per]
            pu = np.ones((len(per), n_f, n_c))
            covers = np.zeros((len(per), n_f), dtype=bool)
            for j, t in enumerate(per):
                if t is not None:  # all candidates blurred at once (ones where not covered)
                    covers[j] = t[0]
                    pu[j, t[0]] = np.exp(blurred(np.log(t[3][t[0]]), self.blur_steps[j])).reshape(-1, n_c)
            self._pu[key] = (flat, pu, covers)
        return self._pu[key]

    def next_probe(self, history: ProbeTable, obs=None) -> Probe | None:
        """The candidate (f_p, A_p, window) of highest expected variance reduction of log omega_n per simulated
        second, or None to stop.

        Every candidate of an amplitude is scored at once. A stable outcome's blurred likelihood enters the
        expected posterior variance only through sums ``sum(posts * G(like) * f)`` over the grid (f = 1, log
        omega_n, its square), and the blur ``G`` is linear, so these are ``sum(like * G^T(posts * f))``: the
        blurred posterior moments ``G^T(posts * f)`` are computed once per decision, each outcome costs one
        likelihood per grid cell and a dot product, and cells where the blurred posterior has no mass
        (below :data:`PRUNE` of its total) are left out. The same draws as a candidate-by-candidate loop, and the
        same utilities up to rounding (and the pruned mass)."""
        from plate_env_agents.design_kernels import stable_sums

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
        n_c = len(self.omega) * self.n_alpha
        flat_posts = posts.reshape(k_mem, n_c)
        log_w = np.broadcast_to(self.log_w, (len(self.omega), self.n_alpha)).ravel()
        f3 = np.stack([np.ones(n_c), log_w, log_w ** 2])  # (3, n_cells): the moments' weights
        # per member: posterior moments (3,) and blurred moments G^T(posts * f) on the cells that carry mass
        moments = flat_posts[:, None, :] * f3[None]  # (K, 3, n_cells)
        plain = moments.sum(-1)  # (K, 3): a member that does not cover a candidate keeps its posterior
        blurred_m, cells_kept = [], []
        for j in range(k_mem):
            g = self._blur_matrices[j]
            bm = np.stack([(g.T @ moments[j, q].reshape(len(self.omega), self.n_alpha)).ravel() for q in range(3)])
            keep = np.flatnonzero(bm[0] > PRUNE * bm[0].sum())
            blurred_m.append(bm[:, keep].T.copy())  # (n_kept, 3)
            cells_kept.append(keep)
        # each member's posterior as a cumulative distribution over the cells: one draw is Generator.choice(n_cells,
        # p=posts[j]) exactly (its cdf, normalised by its last value, searched with one uniform), without re-checking p
        cdfs = [np.cumsum(flat_posts[j]) for j in range(k_mem)]
        cdfs = [c / c[-1] for c in cdfs]
        windows = np.array(self.windows, float)
        se2 = SE_1S ** 2 / windows  # (W,)
        best, best_u = None, -np.inf
        for a in self.amps:
            per, pu, covers = self._design_tables(a)
            done = history.f_p_hz[np.isclose(history.a_p_deg, a)]
            # objects (member, cell) drawn from the posterior, shared by this amplitude's candidates
            members = self.rng.choice(k_mem, size=self.n_samples, p=wts)
            cells = np.array([int(cdfs[j].searchsorted(self.rng.random(), side="right")) for j in members])
            z = self.rng.normal(size=self.n_samples)
            fresh = np.array([not np.any(np.abs(done - f) < 0.5 * self.f_step_hz) for f in self.freqs])
            cand = np.flatnonzero(fresh & covers.any(0))  # a repeat's model error is not independent of the first
            if cand.size == 0:
                continue
            # the unstable outcome: p per candidate and the posterior reweighted by each covering member's p
            cov = covers[:, cand]  # (K, N)
            un_m = np.einsum("kfc,kqc->kfq", pu[:, cand], moments)  # (K, N, 3)
            p_un = np.sum(wts[:, None] * np.where(cov, un_m[:, :, 0], 0.0), axis=0)  # (N,)
            var_un = _mixture_var(np.where(cov[:, :, None], un_m, plain[:, None, :]), wts)
            var_un = np.where(p_un > 0, var_un, v0)
            # the stable outcome: omega_B drawn at each sample's object, for each candidate and window
            y = np.full((self.n_samples, cand.size, windows.size), np.nan)
            for s_i, (j, c) in enumerate(zip(members, cells, strict=True)):
                t = per[j]
                if t is None:
                    continue
                ok = t[0][cand]
                mu_c, s_c = t[1][cand, c], t[2][cand, c]
                sig = np.sqrt(s_c[:, None] ** 2 + se2[None] + self.fm.members[j].sigma_model ** 2)
                y[s_i] = np.where(ok[:, None], mu_c[:, None] + z[s_i] * sig, np.nan)
            valid = ~np.isnan(y)  # (S, N, W): a sample whose member does not cover the candidate is left out
            sums = np.broadcast_to(plain[:, None, None, None, :],
                                   (k_mem, self.n_samples, cand.size, windows.size, 3)).copy()
            for j, t in enumerate(per):
                if t is None or not cov[j].any():
                    continue
                keep = cells_kept[j]
                fj = np.flatnonzero(cov[j])
                sub = np.ix_(cand[fj], cells_kept[j])
                part = np.empty((fj.size, windows.size, self.n_samples, 3))
                stable_sums(np.ascontiguousarray(np.nan_to_num(y[:, fj]).transpose(1, 2, 0)), t[1][sub], t[4][sub],
                            t[5][sub], se2, self.fm.members[j].sigma_model ** 2, blurred_m[j], NU, part)
                sums[j][:, fj] = part.transpose(2, 0, 1, 3)
            var_st = _mixture_var(sums, wts)  # (S, N, W)
            n_valid = valid.sum(0)
            var_st = np.where(n_valid > 0, np.where(valid, var_st, 0.0).sum(0) / np.maximum(n_valid, 1), np.nan)
            expected = p_un[:, None] * var_un[:, None] + (1 - p_un[:, None]) * var_st
            cost = ctx.overhead_s + windows[None] * (1 - p_un[:, None]) + 0.5 * windows[None] * p_un[:, None]
            u = np.where(n_valid > 0, (v0 - expected) / cost, -np.inf)  # (N, W), in the loop's order
            k = int(np.argmax(u))
            if u.flat[k] > best_u:
                best_u = float(u.flat[k])
                best = Probe(float(self.freqs[cand[k // windows.size]]), a, float(windows[k % windows.size]))
        return best


#: Cells whose blurred posterior mass is below this share of the total are left out of the design's sums (their
#: weight in the expected variance is below 1e-12 of a candidate's, far below the utilities' differences).
PRUNE = 1e-14


def _mixture_var(sums: np.ndarray, wts: np.ndarray) -> np.ndarray:
    """Variance of log omega_n of mixtures from the members' sums ``(K, ..., 3)`` of (mass, mass x log omega_n,
    mass x its square) with the members' weights ``wts`` (K,): as :meth:`BayesAgent._pooled_var`."""
    wts = np.asarray(wts).reshape((-1,) + (1,) * (sums.ndim - 2))
    tot = (wts * sums[..., 0]).sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        m1 = (wts * sums[..., 1]).sum(0) / tot
        m2 = (wts * sums[..., 2]).sum(0) / tot
    return np.maximum(m2 - m1 ** 2, 0.0)
