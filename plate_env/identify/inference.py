"""Model-based identification (beyond the paper): the posterior over (omega_n, alpha) of a forward model. Pure.

A forward model (:mod:`plate_env.identify.forward`) is one or more *members* (a physics model's response atlas with its
measured error) and a coherent discrepancy. Given probes:

1. Per member and grid point (omega_eff, alpha), the probes' likelihood: a stable probe with omega_B = y +- e
   scores ``(1 - p) * StudentT_nu(y; mu, s^2 + e^2 + sigma_model^2)``, an unstable one ``p``, with the atlas's mean
   mu, spread s (scatter between placements) and instability probability p at (f_p, A_p). ``p`` is the share of
   unstable repeats shrunk towards 1/2 by Jeffreys' rule, ``(k + 1/2) / (R + 1)`` for k of R repeats: an atlas
   point with none of 4 repeats unstable says p ~ 1/10, not 0. The Student-t (4 degrees of freedom) keeps one
   probe the atlas describes badly from dominating. Each probe's likelihood is averaged over the member's
   ``blur`` (a normal in log omega): the atlas resolves omega_n only to about its node spacing, so a probe on a
   steep flank or an instability boundary between two nodes does not pin omega_n finer than that.
2. The coherent discrepancy: the true omega_n differs from the omega_eff a member's curves match by a factor
   exp(eps), eps normal or Student-t of scale sigma_eps, the same for every probe of one object; so each member's
   likelihood is convolved along log omega with that kernel (never with less than half a grid step), and then
   with the offset between models (``offset_sigma``) when the forward model has one.
3. Priors: log-uniform in omega_n over each member's atlas range, uniform in alpha; members are weighted by their
   evidence times their prior weight (``pooling="evidence"``) or by the prior weight alone (``"fixed"``).

The estimate is the posterior median with equal-tailed intervals (:class:`plate_env.identify.estimate.Posterior`); a
posterior piled against the edge of the identifiable range is reported as a bound, and so is one that the model
extended beyond that range places outside it (:mod:`plate_env.identify.identifiability`). Works with any probes: mixed
amplitudes, one-sided data, curves without a peak; probes outside a member's atlas are left out of that member.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from plate_env.core.jit import kernels
from plate_env.core.probe_table import ProbeTable
from plate_env.identify.estimate import Estimate, Posterior, PredictiveCheck
from plate_env.identify.forward import ForwardModel, Member
from plate_env.surrogate.atlas import Atlas

#: Degrees of freedom of the Student-t likelihood of a stable probe.
NU = 4.0
#: Posterior grid sizes (log omega_n, alpha). 321 omega_n points over the shipped atlases' 1.4pi-45pi is a step of
#: 1.1 % in omega_n: a full sweep's posterior (68 % half-width ~2 %) spans several steps, so the grid floor does
#: not widen it (at 161 points its 68 % intervals held the truth in 0.80 of 120 prior objects, at 321 in 0.73;
#: experiments/results/forward_models_within.md).
N_OMEGA = 321
N_ALPHA = 31
#: The log-omega smoothing is at least this many grid steps (a posterior is never narrower than its grid).
STEP_FLOOR = 0.5


# ----------------------------------------------------------------------------------------------- likelihood
def log_student(resid: np.ndarray, var: np.ndarray, nu: float = NU) -> np.ndarray:
    """Log-density (up to a constant) of a Student-t residual with scale^2 ``var`` and ``nu`` degrees of freedom."""
    return -0.5 * (nu + 1.0) * np.log1p(resid ** 2 / (nu * var)) - 0.5 * np.log(var)


def smoothed_p(p: np.ndarray, n_repeats: int) -> np.ndarray:
    """Jeffreys' estimate of an instability probability from the share ``p`` of ``n_repeats`` repeats."""
    return (p * n_repeats + 0.5) / (n_repeats + 1.0)


def probe_log_likelihood(mu: np.ndarray, spread: np.ndarray, p_unstable: np.ndarray, omega_b: float,
                         stderr: float, unstable: bool, sigma_model: float, n_repeats: int) -> np.ndarray:
    """One probe's log-likelihood on a grid, from the atlas's mean, spread and raw unstable share there."""
    fast = kernels() if mu.ndim == 2 and mu.shape == spread.shape == p_unstable.shape else None
    if fast is not None:  # the same floats: the arithmetic in one pass each side of numpy's logarithms
        out = np.empty(mu.shape)
        flat = out.reshape(-1)
        p_flat = p_unstable.reshape(-1)
        if unstable:
            fast.smoothed(p_flat, float(n_repeats), flat)
            return np.log(out, out=out)
        q, var = np.empty(flat.size), np.empty(flat.size)
        fast.stable_parts(mu.reshape(-1), spread.reshape(-1), p_flat, float(omega_b), float(stderr) ** 2,
                          float(sigma_model) ** 2, float(n_repeats), NU, flat, q, var)
        np.log1p(flat, out=flat)
        fast.stable_combine(flat, np.log1p(q, out=q), np.log(var, out=var), -0.5 * (NU + 1.0), flat)
        return out
    p = smoothed_p(p_unstable, n_repeats)
    if unstable:
        return np.log(p)
    var = spread ** 2 + stderr ** 2 + sigma_model ** 2
    return np.log1p(-p) + log_student(omega_b - mu, var)


def blurred(ll: np.ndarray, blur_steps: float) -> np.ndarray:
    """A log-likelihood grid (..., n_omega, n_alpha) averaged, as a likelihood, over a normal of ``blur_steps`` grid
    steps along log omega (axis -2)."""
    if blur_steps <= 0:
        return ll
    from plate_env.core.filters import gaussian_filter1d  # scipy.ndimage's floats, without its import

    top = ll.max(axis=(-2, -1), keepdims=True)
    like = gaussian_filter1d(np.exp(ll - top), blur_steps, axis=-2, mode="nearest", truncate=4.0)
    return np.log(np.maximum(like, 1e-300)) + top


def member_domain(member: Member, f_hz: float, a_p_deg: float) -> str | None:
    """Why a probe lies outside what a member's atlas describes (None if inside)."""
    atlas = member.atlas
    x = abs(float(a_p_deg))
    if not any(abs(v - x) <= 1e-6 + 1e-5 * x for v in atlas.a_p_deg.tolist()):  # np.isclose(atol=1e-6), in Python
        return f"A_p = {a_p_deg:g} deg is not in {member.label}'s atlas ({[float(x) for x in atlas.a_p_deg]} deg)"
    if not (atlas.f_hz[0] - 1e-9 <= f_hz <= atlas.f_hz[-1] + 1e-9):
        return f"f_p = {f_hz:g} Hz is outside {member.label}'s atlas ({atlas.f_hz[0]:g}-{atlas.f_hz[-1]:g} Hz)"
    return None


def _response(atlas: Atlas, a_p_deg: float, w: np.ndarray, a: np.ndarray):
    from plate_env.core.cache import cached_arrays, content_key
    from plate_env.core.filters import ppoly_eval, ppoly_interval
    from plate_env.core.jit import kernels

    def build() -> dict[str, np.ndarray]:
        from scipy.interpolate import CubicSpline

        ff, ww, aa = np.meshgrid(atlas.f_hz, w, a, indexing="ij")
        arrays = atlas.predict(ff, a_p_deg, ww, aa)
        return {name: CubicSpline(atlas.f_hz, arr, axis=0).c for name, arr in zip(RESPONSE, arrays, strict=True)}

    key = content_key("response", atlas.f_hz, atlas.a_p_deg, atlas.omega_n, atlas.alpha, atlas.mean, atlas.spread,
                      atlas.p_unstable, float(a_p_deg), np.asarray(w, float), np.asarray(a, float))
    coef = cached_arrays("response", key, build, mmap=True,
                         note=f"computing the {atlas.physics}/{atlas.model} atlas's response at A_p = {a_p_deg:g} deg "
                              f"on a {len(w)} x {len(a)} posterior grid")
    x = np.asarray(atlas.f_hz, float)
    coefs = [np.asarray(coef[name]) for name in RESPONSE]  # CubicSpline's own polynomials, as its PPoly evaluates
    inside = _covered(atlas, w, a)
    flats = [c.reshape(c.shape[0], c.shape[1], -1) for c in coefs]

    def at(f_hz: float):
        f = float(f_hz)
        fast = kernels() if f == f and all(c.ndim == 4 for c in coefs) else None
        if fast is not None:  # the same floats in one pass (plate_env.core.grid_kernels)
            i, s = ppoly_interval(x, f)
            out = np.empty((3, *coefs[0].shape[2:]))
            flat = out.reshape(3, -1)
            fast.ppoly3_at(*flats, i, s, flat[0], flat[1], flat[2])
            return out[0], out[1], out[2]
        m, s, p = (ppoly_eval(c, x, f) for c in coefs)
        return m, np.maximum(s, 0.0), np.clip(p, 0.0, 1.0)

    return at, inside


#: The atlas quantities a member's response gives (mean, spread, instability share).
RESPONSE = ("mean", "spread", "p_unstable")


def member_response(member: Member, a_p_deg: float, w: np.ndarray, a: np.ndarray):
    """``(f_hz -> (mean, spread, p_unstable)), inside``: a member's atlas on the grid ``w`` x ``a`` at one amplitude
    as cubic splines along f_p (exact at the atlas's nodes; built once per atlas, amplitude and grid, kept on the
    atlas, their coefficients in the disk cache of :mod:`plate_env.core.cache`, keyed by the atlas's arrays, the
    amplitude and the grid), and the mask of grid points inside its omega_n and alpha ranges."""
    key = ("response", abs(float(a_p_deg)), float(w[0]), float(w[-1]), len(w), float(a[0]), float(a[-1]), len(a))
    return member.atlas.cached(key, lambda: _response(member.atlas, abs(float(a_p_deg)), w, a))


def _covered(atlas: Atlas, w: np.ndarray, a: np.ndarray) -> np.ndarray:
    return ((w[:, None] >= atlas.omega_n[0] * (1 - 1e-9)) & (w[:, None] <= atlas.omega_n[-1] * (1 + 1e-9))
            & (a[None, :] >= atlas.alpha[0] - 1e-9) & (a[None, :] <= atlas.alpha[-1] + 1e-9))


def member_coverage(member: Member, w: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The grid points (n_omega, n_alpha) inside a member's atlas ranges (read-only: kept on the atlas per grid)."""
    w, a = np.asarray(w, float), np.asarray(a, float)

    def build() -> np.ndarray:
        inside = _covered(member.atlas, w, a)
        inside.flags.writeable = False
        return inside

    return member.atlas.cached(("coverage", w.tobytes(), a.tobytes()), build)


def member_rows(member: Member, w: np.ndarray) -> slice:
    """The rows of the omega grid ``w`` (sorted) inside a member's omega_n range: its likelihood is computed there
    only (outside, its prior is zero; a grid padded for a wide discrepancy adds no work per probe)."""
    lo = int(np.searchsorted(w, member.atlas.omega_n[0] * (1 - 1e-9), side="left"))
    hi = int(np.searchsorted(w, member.atlas.omega_n[-1] * (1 + 1e-9), side="right"))
    return slice(lo, max(hi, lo))


def member_log_likelihood(member: Member, table: ProbeTable, w: np.ndarray, a: np.ndarray,
                          only: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Sum of the probes' (blurred) log-likelihoods on the grid (n_omega, n_alpha) for one member, and how many
    probes lay outside its domain (left out); ``only`` (a mask over the probes) restricts the sum."""
    total = np.zeros((len(w), len(a)))
    skipped = 0
    steps = member.blur / math.log(w[1] / w[0])
    rows = member_rows(member, w)
    sub = w[rows]
    counts: dict[tuple, int] = {}
    inside: dict[tuple[float, float], bool] = {}
    for k in range(len(table)):
        if only is not None and not only[k]:
            continue
        key = probe_key(table, k)
        if key[:2] not in inside:
            inside[key[:2]] = member_domain(member, *key[:2]) is None
        if not inside[key[:2]]:
            skipped += 1
            continue
        counts[key] = counts.get(key, 0) + 1
    if sub.size == 0:
        return total, skipped
    for (f, amp, y, e, unstable), n in counts.items():  # exact repeats: one term times their count (same product)
        mu, s, p = member_response(member, amp, sub, a)[0](f)
        total[rows] += n * blurred(probe_log_likelihood(mu, s, p, y, e, unstable, member.sigma_model,
                                                        member.atlas.n_repeats), steps)
    return total, skipped


def probe_key(table: ProbeTable, k: int) -> tuple[float, float, float, float, bool]:
    """Row ``k``'s ``(f_p_hz, a_p_deg, omega_b_deg_s, stderr_deg_s, unstable)``: rows with equal keys are exact
    repeats, whose log-likelihood terms are equal, so the likelihood computes one and multiplies it by their count.

    Only exact repeats are pooled. Rows at one (f_p, A_p) with different omega_B are *not* merged into their
    inverse-variance weighted mean: for Gaussian errors that product equals the mean's likelihood (up to a
    constant) for the measurement-error part only, but here each row's term is a Student-t of scale^2
    ``spread^2 + stderr^2 + sigma_model^2`` -- the atlas spread and the model error enter every row independently
    -- times its own stable/unstable flag, so merging would change the posterior (docs/hardening.md, item 11)."""
    return (float(table.f_p_hz[k]), float(table.a_p_deg[k]), float(table.omega_b_deg_s[k]),
            float(table.stderr_deg_s[k]), bool(table.unstable[k]))


def _probe_keys(table: ProbeTable) -> list[tuple[float, float, float, float, bool]]:
    """:func:`probe_key` of every row (the same tuples, read in one pass)."""
    return list(zip(np.asarray(table.f_p_hz, float).tolist(), np.asarray(table.a_p_deg, float).tolist(),
                    np.asarray(table.omega_b_deg_s, float).tolist(), np.asarray(table.stderr_deg_s, float).tolist(),
                    [bool(u) for u in table.unstable.tolist()], strict=True))


def distinct_probes(table: ProbeTable) -> int:
    """How many distinct rows (:func:`probe_key`) a table has: the likelihood's cost grows with these."""
    return len({probe_key(table, k) for k in range(len(table))})


# ----------------------------------------------------------------------------------------------- posterior
def _smooth_log_omega(prob: np.ndarray, sigma_steps: float, nu: float = math.inf) -> np.ndarray:
    """Convolve along axis 0 (a uniform log-omega grid) with a normal of scale ``sigma_steps`` grid steps, or a
    Student-t with ``nu`` degrees of freedom; mass pushed beyond the grid is lost (the grid reaches
    ``forward.pad_sigmas`` scales beyond the models' range)."""
    from plate_env.core.filters import fftconvolve_same, gaussian_filter1d  # scipy's floats, without its import

    if math.isinf(nu):
        return gaussian_filter1d(prob, sigma_steps, axis=0, mode="constant", cval=0.0, truncate=5.0)
    half = min(int(math.ceil(sigma_steps * 40)), prob.shape[0])
    kernel = _t_kernel(half, sigma_steps, nu).reshape((-1,) + (1,) * (prob.ndim - 1))
    return np.maximum(fftconvolve_same(prob, kernel), 0.0)  # zero beyond the grid, as above


@functools.lru_cache(maxsize=64)
def _t_kernel(half: int, sigma_steps: float, nu: float) -> np.ndarray:
    """The normalised Student-t kernel of :func:`_smooth_log_omega` on ``2 half + 1`` grid steps (read-only: it is
    shared by every call with these arguments). scipy's ``t.pdf`` computes it once per machine: the kernel is kept
    in the disk cache (:mod:`plate_env.core.cache`), so a fit does not import scipy.stats."""
    from plate_env.core.cache import cached_arrays, content_key

    def build() -> dict[str, np.ndarray]:
        from scipy.stats import t

        kernel = t.pdf(np.arange(-half, half + 1) / sigma_steps, nu)
        return {"kernel": kernel / kernel.sum()}

    kernel = np.array(cached_arrays("t-kernel", content_key("t-kernel", int(half), float(sigma_steps), float(nu)),
                                    build)["kernel"])
    kernel.flags.writeable = False
    return kernel


def _log_evidence(ll: np.ndarray, inside: np.ndarray, sigma_steps: float, nu: float = math.inf,
                  offset: tuple[float, float] = (0.0, math.inf), peaked: tuple[np.ndarray, float] | None = None
                  ) -> tuple[np.ndarray, float]:
    """The smoothed likelihood grid of one member (unnormalised, peak-scaled) and its log evidence under a prior
    uniform over the grid points it covers; ``offset`` (scale in grid steps, nu): a second smoothing, the offset
    between models. ``peaked``: ``(exp(ll - top), top)`` over the covered points, when the caller has it."""
    if peaked is None:
        ll = np.where(inside, ll, -np.inf)
        top = float(ll.max())
        peaked = (np.exp(ll - top), top)
    top = peaked[1]
    like = _smooth_log_omega(peaked[0], sigma_steps, nu)
    if offset[0] > 0:
        like = _smooth_log_omega(like, offset[0], offset[1])
    mass = float(like.sum())
    return like, top + math.log(max(mass, 1e-300)) - math.log(max(int(inside.sum()), 1))


def pool(fm: ForwardModel, w: np.ndarray, a: np.ndarray, log_likes: Sequence[np.ndarray],
         skipped: Sequence[int] = (), evidence_likes: Sequence[np.ndarray] | None = None) -> Posterior:
    """Combine the members' log-likelihood grids into the posterior: each member's prior is uniform over the grid
    points its atlas covers, its likelihood is smoothed along log omega by the discrepancy (at least
    ``STEP_FLOOR`` grid steps), and members are weighted by evidence x prior weight or by prior weight alone.
    ``evidence_likes``: the members' log-likelihoods of the probes every member describes, which their evidences
    compare (default ``log_likes``: every member describes every probe)."""
    step = math.log(w[1] / w[0])
    sigma = max(fm.sigma_eps, STEP_FLOOR * step)
    nu = fm.eps_nu if fm.sigma_eps > STEP_FLOOR * step else math.inf
    offset = (fm.offset_sigma / step, fm.offset_nu)
    parts, raw, log_z = [], [], []
    for i, (m, ll) in enumerate(zip(fm.members, log_likes, strict=True)):
        inside = member_coverage(m, w, a)
        masked = np.where(inside, ll, -np.inf)
        top = float(masked.max())
        peaked = np.exp(masked - top)  # the member's likelihood over its prior's support, peak-scaled
        own = peaked.sum(1)
        raw.append(own / own.sum())
        like, lz = _log_evidence(ll, inside, sigma / step, nu, offset, peaked=(peaked, top))
        if evidence_likes is not None:
            lz = _log_evidence(evidence_likes[i], inside, sigma / step, nu, offset)[1]
        mass = float(like.sum())
        parts.append(like / mass if mass > 0 else like)
        log_z.append(lz + math.log(m.weight))
    log_z = np.array(log_z)
    if fm.pooling == "evidence":
        wts = np.exp(log_z - log_z.max())
    else:
        wts = np.array([m.weight for m in fm.members], dtype=float)
    wts = wts / wts.sum()
    prob = sum(wt * part for wt, part in zip(wts, parts, strict=True))
    prob = prob / prob.sum()
    return Posterior(omega_n=w, alpha=a, prob=prob, members=tuple(m.label for m in fm.members),
                     member_weights=tuple(float(x) for x in wts),
                     skipped=tuple(skipped) or (0,) * len(fm.members),
                     sigma_conv=math.hypot(sigma, fm.offset_sigma),
                     identifiable_range=fm.identifiable_range,
                     model_omega=sum(wt * r for wt, r in zip(wts, raw, strict=True)))


def posterior(fm: ForwardModel, table: ProbeTable, n_omega: int = N_OMEGA, n_alpha: int = N_ALPHA) -> Posterior:
    """The posterior of ``fm`` given the probes (the prior alone when there are none). A member's posterior uses
    every probe it describes; members are compared (their evidences) on the probes all of them describe."""
    w, a = fm.grid(n_omega, n_alpha)
    lls, skipped = zip(*(member_log_likelihood(m, table, w, a) for m in fm.members), strict=True)
    evidence = None
    if len(fm.members) > 1 and any(skipped):
        places = {(float(f), float(amp)) for f, amp in zip(table.f_p_hz, table.a_p_deg, strict=True)}
        in_all = {fa: all(member_domain(m, *fa) is None for m in fm.members) for fa in places}
        common = np.array([in_all[float(f), float(amp)] for f, amp in zip(table.f_p_hz, table.a_p_deg, strict=True)],
                          dtype=bool)
        evidence = [member_log_likelihood(m, table, w, a, only=common)[0] for m in fm.members]
    return pool(fm, w, a, lls, skipped, evidence)


# ----------------------------------------------------------------------------------------------- predictive check
#: Replicated sweeps drawn for the check's p-value (from a fixed seed: the check is a pure function of its input).
CHECK_DRAWS = 4000
CHECK_SEED = 20261202
#: How many of a member's blur scales (sd of log omega_n) each probe may move along omega_n in the check.
CHECK_BLURS = 1.0
#: ... and at least this share of the member's atlas node interval (median, in log omega_n): the atlas knows the
#: response at its omega_n nodes and interpolates between them, so no probe is trusted to place omega_n finer than
#: the farthest an object lies from a node, half an interval. Without it a member with no blur (the shipped point
#: mass) refused live in-model episodes whose probes sat on a steep flank between nodes, tens of model scales off
#: the spline at the truth (issue 38 item 3; rates in experiments/results/check_false_refusal.md).
CHECK_NODE_SHARE = 0.5
#: Whether each probe's scale in the check holds the atlas's interpolation error along alpha, measured on its own
#: nodes (:mod:`plate_env.identify.interp_error`): the node share covers omega_n, not a response that peaks in alpha
#: between alpha nodes (issue 38 item 3: 3 of 200 live bayes episodes refused without it; a reach along alpha let
#: the 60pi object of tests/test_hardening.py item 1 through, this does not).
CHECK_ALPHA_ERROR = True


def _surprise(z2: np.ndarray, stable: np.ndarray, p: np.ndarray, nu: float = NU) -> np.ndarray:
    """The check's statistic per probe (last axis summed): Student-t surprise of stable residuals, flag surprise."""
    flag = -np.log(np.where(stable, 1.0 - p, p))
    return (np.where(stable, 0.5 * (nu + 1.0) * np.log1p(z2 / nu), 0.0) + flag).sum(-1)


@functools.lru_cache(maxsize=32)
def _check_replicates(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The check's replicate draws for ``n`` probes from its fixed seed (they depend on nothing else): the uniforms
    that decide each replicate probe's stability (CHECK_DRAWS, n) and the Student-t surprise of its residual,
    ``0.5 (NU + 1) log1p(z^2 / NU)`` as :func:`_surprise` computes it (read-only: shared by every check of n
    probes)."""
    rng = np.random.default_rng(CHECK_SEED)
    u = rng.random((CHECK_DRAWS, n))
    z2 = rng.standard_t(NU, (CHECK_DRAWS, n)) ** 2
    part = 0.5 * (NU + 1.0) * np.log1p(z2 / NU)
    u.flags.writeable = False
    part.flags.writeable = False
    return u, part


def check_reach_log(member: Member) -> float:
    """How far (log omega_n) each probe may move along omega_n in :func:`predictive_check`: ``CHECK_BLURS`` of the
    member's blur, at least ``CHECK_NODE_SHARE`` of its atlas's median omega_n node interval (0 for an atlas with
    one node)."""
    nodes = np.asarray(member.atlas.omega_n, float)
    spacing = float(np.median(np.diff(np.log(nodes)))) if nodes.size > 1 else 0.0
    return max(CHECK_BLURS * member.blur, CHECK_NODE_SHARE * spacing)


def respond(member: Member, a_p_deg: float, w: np.ndarray, a: np.ndarray, f_hz: float):
    """``(mean, spread, p_unstable)`` of a member's atlas on the grid ``w`` x ``a`` at one probe
    (:func:`member_response` at ``f_hz``). The check's default; a
    :class:`~plate_env.identify.posterior_state.PosteriorState` passes its own, which reuses the arrays its updates
    computed."""
    return member_response(member, a_p_deg, w, a)[0](f_hz)


def predictive_check(fm: ForwardModel, table: ProbeTable, post: Posterior,
                     response: Callable = respond) -> PredictiveCheck:
    """A posterior predictive check of the probes under ``fm`` (see :class:`PredictiveCheck`). Pure: replicates
    come from a fixed seed.

    The object checked is the one of the member of highest posterior weight that explains the probes best (least
    surprise over its whole grid); replicated sweeps are drawn from that object. Checking at a fitted point makes
    the test conservative for honest data (a fit explains its own data better than the truth does), so a failure
    is data the model cannot produce, not bad luck. ``response``: :func:`respond` or a function that gives the same
    arrays."""
    i = int(np.argmax(post.member_weights)) if post.member_weights else 0
    m = fm.members[i]
    w, a = post.omega_n, post.alpha
    if CHECK_ALPHA_ERROR:
        response = _with_alpha_error(response)
    sub = w[member_rows(m, w)]
    places = {(float(f), float(amp)) for f, amp in zip(table.f_p_hz, table.a_p_deg, strict=True)}
    in_m = {fa: member_domain(m, *fa) is None for fa in places}
    idx = np.array([k for k, (f, amp) in enumerate(zip(table.f_p_hz, table.a_p_deg, strict=True))
                    if in_m[float(f), float(amp)]], dtype=int)
    n = idx.size
    if n == 0 or sub.size == 0:
        return PredictiveCheck(statistic=0.0, p_value=1.0, n_probes=0, member=m.label, worst=None)

    known: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}

    def terms(k: int):  # a probe's z-scores and instability shares over the grid (once per distinct probe)
        key = keys[k]
        if key not in known:
            amp = float(table.a_p_deg[k])
            mk, sk, pk = response(m, amp, sub, a, float(table.f_p_hz[k]))
            sd = np.sqrt(sk ** 2 + float(table.stderr_deg_s[k]) ** 2 + m.sigma_model ** 2)
            known[key] = (float(table.omega_b_deg_s[k]) - mk) / sd, smoothed_p(pk, m.atlas.n_repeats)
        return known[key]

    # no probe is trusted to pin omega_n finer than the member's blur or its atlas's nodes: each probe's surprise
    # is its least within check_reach_log(m) along log omega_n
    reach = int(round(check_reach_log(m) / math.log(w[1] / w[0]))) if len(w) > 1 else 0
    total = np.zeros((sub.size, a.size))
    counts: dict[tuple, list[int]] = {}
    keys = _probe_keys(table)
    for k in idx:
        counts.setdefault(keys[k], []).append(int(k))
    fast = kernels() if reach == 0 else None
    for ks in counts.values():  # the surprise of every grid object, probe by probe (exact repeats computed once)
        if fast is not None:  # the same floats, the arithmetic in kernels around numpy's logarithms
            key = keys[ks[0]]
            known[key] = _surprise_into(fast, total, len(ks), m, key, response(m, key[1], sub, a, key[0]))
            continue
        z, pu = terms(ks[0])
        one = _surprise((z ** 2)[..., None], np.array([not table.unstable[ks[0]]]), pu[..., None])
        if reach > 0:
            from plate_env.core.filters import minimum_filter1d  # scipy.ndimage's, without its import

            one = minimum_filter1d(one, 2 * reach + 1, axis=0)
        total += len(ks) * one
    total = np.where(member_coverage(m, sub, a), total, np.inf)
    c = np.unravel_index(int(np.argmin(total)), total.shape)
    stable = ~table.unstable[idx]
    rows_c = slice(max(c[0] - reach, 0), c[0] + reach + 1)
    z, p_c = [], []
    best: dict[tuple, tuple[float, float]] = {}
    for k, st in zip(idx, stable, strict=True):  # each probe at its best omega_n within the reach of the object
        key = keys[k]
        if key not in best:
            zz, pp = terms(k)
            zz, pp = zz[rows_c, c[1]], pp[rows_c, c[1]]
            j = int(np.argmin(_surprise((zz ** 2)[:, None], np.array([st]), pp[:, None]))) if zz.size > 1 else 0
            best[key] = (zz[j], pp[j])
        z.append(best[key][0])
        p_c.append(best[key][1])
    z, p_c = np.array(z), np.array(p_c)
    t_obs = float(_surprise(z ** 2, stable, p_c))
    u_rep, t_part = _check_replicates(n)
    # _surprise(z2_rep, stable_rep, p_c) term by term: its t part drawn once, the flags' logs taken per probe
    if fast is not None and n <= 128:
        exceed = fast.replicates_at_least(u_rep, t_part, p_c, -np.log(1.0 - p_c), -np.log(p_c), t_obs)
    else:
        stable_rep = u_rep >= p_c
        t_rep = np.where(stable_rep, t_part + -np.log(1.0 - p_c), -np.log(p_c)).sum(-1)
        exceed = np.count_nonzero(t_rep >= t_obs)
    p_value = float((1 + exceed) / (CHECK_DRAWS + 1))
    worst = None
    if np.any(stable):
        j = int(np.argmax(np.where(stable, np.abs(z), -1.0)))
        worst = (float(table.f_p_hz[idx[j]]), float(table.a_p_deg[idx[j]]), float(z[j]))
    return PredictiveCheck(statistic=t_obs, p_value=p_value, n_probes=n, member=m.label, worst=worst)


def _with_alpha_error(response: Callable) -> Callable:
    """``response`` with the atlas's alpha interpolation error (:func:`~plate_env.identify.interp_error.alpha_error`)
    added in quadrature to its spread: the check's scale of a stable probe becomes
    ``sqrt(spread^2 + alpha_error^2 + stderr^2 + sigma_model^2)``."""
    from plate_env.identify.interp_error import alpha_error

    def with_error(m: Member, a_p_deg: float, w: np.ndarray, a: np.ndarray, f_hz: float):
        mk, sk, pk = response(m, a_p_deg, w, a, f_hz)
        return mk, np.hypot(sk, alpha_error(m.atlas, a_p_deg, f_hz, w, a)), pk

    return with_error


def _surprise_into(fast, total: np.ndarray, count: int, m: Member, key: tuple, response):
    """``total += count * _surprise(...)`` of the probe ``key`` (:func:`probe_key`) over the grid (``total``
    contiguous), as :func:`predictive_check`'s numpy code computes it (the same floats), with its arithmetic in
    :mod:`plate_env.core.grid_kernels`; returns the probe's (z, smoothed p) grids (z is zeros for an unstable probe:
    its surprise does not read z)."""
    mk, sk, pk = (v.reshape(-1) for v in response)
    ps = np.empty(response[0].shape)
    flat = ps.reshape(-1)
    if key[4]:  # unstable
        fast.smoothed(pk, float(m.atlas.n_repeats), flat)
        fast.check_add_unstable(total.reshape(-1), np.log(flat), count)
        return np.zeros(ps.shape), ps
    z, x, omp = np.empty(ps.shape), np.empty(flat.size), np.empty(flat.size)
    fast.check_parts(mk, sk, pk, key[2], key[3] ** 2, m.sigma_model ** 2, float(m.atlas.n_repeats), NU,
                     z.reshape(-1), x, omp, flat)
    fast.check_add(total.reshape(-1), np.log1p(x, out=x), np.log(omp, out=omp), 0.5 * (NU + 1.0), count)
    return z, ps


@dataclass(frozen=True)
class PredictedCurve:
    """A forward model's response at an estimate, on a frequency grid (:func:`predicted_curve`).

    Attributes:
        f_hz: the plate frequencies, Hz. mean: omega_B where the probes are stable, deg/s. p_unstable: the
            model's probability that a probe is unstable. inside: f_hz within the member's atlas (outside it the
            atlas is clipped, so ``mean`` there is an extrapolation, not a prediction). label: the member's label.
    """

    f_hz: np.ndarray
    mean: np.ndarray
    p_unstable: np.ndarray
    inside: np.ndarray
    label: str

    def predicts_stable(self, threshold: float = 0.5) -> np.ndarray:
        """Where the model predicts a stable probe (p_unstable below ``threshold``) inside its atlas."""
        return self.inside & (self.p_unstable < threshold)


def predicted_curve(fm: ForwardModel, est: Estimate, f_hz: np.ndarray, a_p_deg: float) -> PredictedCurve | None:
    """The forward model's response (mean omega_B and p_unstable) at the estimate (omega_n_hat, alpha_hat) and
    amplitude ``a_p_deg``, from the member of highest posterior weight (the curve the estimate says the data
    follow). None when ``est`` is not an atlas point estimate (no estimate, a bound, the Lorentz method) or that
    member has no atlas at this amplitude. An atlas estimate is the one that carries its posterior (the Lorentz and
    the calibrated readings carry none)."""
    post = est.posterior
    if not est.ok or post is None or est.alpha is None:
        return None
    i = int(np.argmax(post.member_weights)) if post.member_weights else 0
    m = fm.members[i]
    if not np.any(np.isclose(m.atlas.a_p_deg, abs(a_p_deg), atol=1e-6)):
        return None
    f = np.asarray(f_hz, float)
    mean, _, pu = m.atlas.predict(f, abs(a_p_deg), est.omega_n, est.alpha)
    inside = (f >= m.atlas.f_hz[0] - 1e-9) & (f <= m.atlas.f_hz[-1] + 1e-9)
    return PredictedCurve(f_hz=f, mean=np.asarray(mean, float), p_unstable=np.asarray(pu, float), inside=inside,
                          label=m.label)


def identify_atlas(table: ProbeTable, fm: ForwardModel) -> Estimate:
    """omega_n and alpha as posterior medians of ``fm``, with equal-tailed 68 % / 95 % intervals; a bound (``ok``
    False) when the posterior piles against the edge of the identifiable range; no estimate when a probe lies
    outside every member's atlas (it is named, not dropped), when the probes fail the predictive check
    (:func:`predictive_check`: data the model cannot explain) or when alpha piles against the edge of the
    friction angles the model covers (:meth:`Posterior.alpha_edge`). The estimate carries its check. From scratch;
    :class:`plate_env.identify.posterior_state.PosteriorState` gives the same estimate probe by probe."""
    from plate_env.identify.identifiability import extended_model

    orphans = sorted({reason for f, amp in zip(table.f_p_hz, table.a_p_deg, strict=True)
                      if all((reason := member_domain(m, float(f), float(amp))) is not None for m in fm.members)})
    wide = extended_model(fm)
    extended = None if wide is None else (lambda: posterior(wide, table, N_OMEGA))
    return atlas_estimate(fm, table, orphans, lambda: posterior(fm, table), extended=extended)


def atlas_estimate(fm: ForwardModel, table: ProbeTable, orphans: Sequence[str],
                   make_posterior: Callable[[], Posterior], response: Callable = respond,
                   extended: Callable[[], Posterior] | None = None) -> Estimate:
    """The estimate of :func:`identify_atlas` from the probes (counted, and read by the predictive check), the
    reasons of probes no member describes (``orphans``: then no estimate) and the posterior (``make_posterior()``,
    called only when it is needed); ``response`` is passed to :func:`predictive_check`. ``extended()``: the
    posterior of ``fm`` extended beyond its identifiable range
    (:func:`plate_env.identify.identifiability.extended_model`), read only when the estimate would stand: more
    than EDGE_MASS of it outside the range makes the estimate a bound (or no estimate when on both sides)."""
    base = {"method": "atlas", "n_probes": len(table), "n_unstable": int(table.unstable.sum()), "forward": fm.name}
    if len(table) == 0:
        return Estimate(ok=False, reason="no probes", **base)
    if orphans:  # probes no member describes are not dropped silently
        return Estimate(ok=False, reason="; ".join(orphans) + f": leave those probes out or use a forward model "
                        f"that describes them (not {fm.name!r})", **base)
    post = make_posterior()
    om, al = post.omega(), post.alpha_marginal()
    check = predictive_check(fm, table, post, response)
    fields = dict(omega_n=om.value, omega_n_stderr=om.stderr, omega_n_ci68=om.ci68, omega_n_ci95=om.ci95,
                  alpha=al.value, alpha_stderr=al.stderr, posterior=post, check=check, **base)
    side = post.edge()
    if not check.passed:  # data no object of the model could make: no number and no bound, the check says why
        edge = "" if side is None else f" (its best fit piles at the {side} edge of the range it can identify)"
        return Estimate(ok=False, reason=check.reason(fm.name) + edge, **fields)
    alpha_side = post.alpha_edge()
    if alpha_side is not None and (side is None or post.edge_at_inner_alpha() != side):
        # alpha at its edge: no estimate, and no omega_n bound unless omega_n piles at that side for the friction
        # angles inside the range too (then the pile is the data's, not bought by the alpha edge: the bound below)
        a_lo, a_hi = fm.alpha_range
        also = "" if side is None else (f"; omega_n piles at the {side} edge only with alpha at its edge, so no "
                                        "bound is given")
        head = (f"alpha is {alpha_side} the friction angles {fm.name!r} covers ({math.degrees(a_lo):.0f}-"
                f"{math.degrees(a_hi):.0f} deg)")
        if side is None and (verdict := _beyond(fm, om.ci95, extended)) is not None:  # beyond the omega_n range too
            return Estimate(ok=False, bound=verdict.bound, beyond=verdict.side,
                            reason=f"{head}, and {verdict.reason(om.value, fm.name)}", **fields)
        return Estimate(ok=False, reason=(
            f"{head}: the posterior piles at that edge, so its omega_n cannot be trusted" + also), **fields)
    if side is not None:
        lo, hi = post.identifiable_range
        bound = ("above", om.ci95[0]) if side == "above" else ("below", om.ci95[1])
        return Estimate(ok=False, bound=bound, beyond=side, reason=(
            f"omega_n is {side} the range {fm.name!r} can identify ({lo / math.pi:.3g}-{hi / math.pi:.3g} pi rad/s): "
            f"omega_n {'>' if side == 'above' else '<'} {bound[1]:.4g} rad/s at 95 %"), **fields)
    if (verdict := _beyond(fm, om.ci95, extended)) is not None:  # an object outside the range? (issue 37 item 1)
        return Estimate(ok=False, bound=verdict.bound, beyond=verdict.side, reason=verdict.reason(om.value, fm.name),
                        **fields)
    return Estimate(ok=True, **fields)


def _beyond(fm: ForwardModel, ci95: tuple[float, float], extended: Callable[[], Posterior] | None):
    """The extended posterior's verdict (:func:`plate_env.identify.identifiability.outside_mass`) when it places
    the probes' object beyond ``fm``'s identifiable range, else None (also without an extended model)."""
    if extended is None:
        return None
    from plate_env.identify.identifiability import outside_mass

    verdict = outside_mass(extended(), fm.identifiable_range, ci95)
    return verdict if verdict.side is not None else None


# ----------------------------------------------------------------------------------------------- estimation
def fit_sigma_model(resid: np.ndarray, spread: np.ndarray, stderr: np.ndarray, nu: float = NU) -> float:
    """Maximum-likelihood model error (deg/s) of an atlas from live stable probes at held-out points: residuals
    ``y - mu`` are Student-t with scale^2 ``spread^2 + stderr^2 + sigma^2``."""
    from scipy.optimize import minimize_scalar

    r = np.asarray(resid, float)
    base = np.asarray(spread, float) ** 2 + np.asarray(stderr, float) ** 2
    if r.size == 0:
        raise ValueError("no held-out residuals to estimate a model error from")

    def nll(log_s: float) -> float:
        return -float(np.sum(log_student(r, base + math.exp(2 * log_s), nu)))

    best = minimize_scalar(nll, bounds=(math.log(1e-3), math.log(1e3)), method="bounded")
    return float(math.exp(best.x))


#: Gauss-Hermite nodes and weights (61) for averaging over a normal error: x = sqrt(2) sd node, weight / sqrt(pi).
GAUSS_HERMITE = np.polynomial.hermite.hermgauss(61)


def _t_pdf(x: np.ndarray, nu: float, scale) -> np.ndarray:
    """Student-t density (``scipy.stats.t.pdf(x, nu, scale=scale)``, without its per-call overhead: the fits call it
    thousands of times)."""
    from scipy.special import gammaln

    c = gammaln((nu + 1) / 2) - gammaln(nu / 2) - 0.5 * math.log(nu * math.pi)
    z = np.asarray(x, float) / scale
    return np.exp(c - 0.5 * (nu + 1) * np.log1p(z * z / nu)) / scale


def discrepancy_log_density(eps: np.ndarray, post_sd: np.ndarray, sigma: float, nu: float = math.inf) -> np.ndarray:
    """Log-density of ``eps = log(truth / estimate)`` when the posterior's own error is normal (sd ``post_sd``) and
    the discrepancy, independent of it, is normal (``nu`` inf) or Student-t with scale ``sigma``: their sum, the
    convolution the posterior applies (Gauss-Hermite quadrature over the normal part for finite ``nu``)."""
    from scipy import stats

    e = np.asarray(eps, float)
    sd = np.asarray(post_sd, float)
    if math.isinf(nu) or sigma <= 0.0:
        return stats.norm.logpdf(e, scale=np.sqrt(sd ** 2 + sigma ** 2))
    x, w = GAUSS_HERMITE
    d = e[..., None] - math.sqrt(2.0) * sd[..., None] * x  # the discrepancy's share of eps at each node
    dens = (w * _t_pdf(d, nu, sigma)).sum(-1) / math.sqrt(math.pi)
    wide = sd > 0.2 * sigma  # a normal part wider than the t's core: quadrature is accurate; else the t dominates
    narrow = _t_pdf(e, nu, np.sqrt(sigma ** 2 + sd ** 2))
    return np.log(np.maximum(np.where(wide, dens, narrow), 1e-300))


def fit_sigma_eps(eps: np.ndarray, post_sd: np.ndarray, nu: float = math.inf) -> float:
    """Maximum-likelihood coherent discrepancy (scale of log omega_n) from held-out objects: ``eps = log(truth /
    estimate)`` is the posterior's own normal error (sd ``post_sd``) plus the discrepancy, normal or Student-t with
    ``nu`` degrees of freedom (:func:`discrepancy_log_density`); 0 when the posteriors already explain the errors."""
    from scipy.optimize import minimize_scalar

    e = np.asarray(eps, float)
    sd = np.asarray(post_sd, float)
    if e.size == 0:
        raise ValueError("no held-out objects to estimate a discrepancy from")

    def nll(sig: float) -> float:
        return -float(np.sum(discrepancy_log_density(e, sd, sig, nu)))

    best = minimize_scalar(nll, bounds=(0.0, 2.0), method="bounded")
    return float(best.x) if nll(best.x) < nll(0.0) else 0.0


#: Degrees of freedom tried when a discrepancy is fitted (inf: normal); the one of highest likelihood is kept.
NU_CHOICES = (1.0, 1.5, 2.0, 3.0, 5.0, 10.0, math.inf)


def fit_discrepancy(eps: np.ndarray, post_sd: np.ndarray, nus: Sequence[float] = NU_CHOICES) -> tuple[float, float]:
    """``(nu, sigma)`` of a discrepancy by maximum likelihood with each posterior approximated as normal
    (:func:`fit_sigma_eps` per nu, then the nu of highest likelihood). :func:`fit_discrepancy_exact` uses the
    posteriors themselves; this serves where only ``(eps, sd)`` pairs are kept."""
    eps, sd = np.asarray(eps, float), np.asarray(post_sd, float)
    best = (-np.inf, math.inf, 0.0)
    for nu in nus:
        sigma = fit_sigma_eps(eps, sd, nu)
        ll = float(np.sum(discrepancy_log_density(eps, sd, sigma, nu)))
        if ll > best[0] + 1e-9:
            best = (ll, nu, sigma)
    return best[1], best[2]


def truth_log_density(post: Posterior, omega_true: float, sigma: float, nu: float = math.inf) -> float:
    """Log-density (per unit of log omega_n) of ``omega_true`` under a posterior whose members' own marginal
    (``post.model_omega``, before any discrepancy) is smoothed by a discrepancy of scale ``sigma`` (at least
    ``STEP_FLOOR`` grid steps) and ``nu`` degrees of freedom, as :func:`pool` applies it; the grid is padded as
    :meth:`ForwardModel.grid` pads it. -690 (1e-300) beyond the padded grid."""
    from plate_env.identify.forward import pad_log

    lw = np.log(post.omega_n)
    step = float(lw[1] - lw[0])
    raw = post.marginal_omega() if post.model_omega is None else post.model_omega
    sig = max(sigma, STEP_FLOOR * step)
    nu = nu if sigma > STEP_FLOOR * step else math.inf
    k = int(math.ceil(pad_log(sig, nu) / step))
    prob = _smooth_log_omega(np.pad(raw, k), sig / step, nu)
    dens = prob / (prob.sum() * step)
    grid = lw[0] + step * np.arange(-k, lw.size + k)
    x = math.log(omega_true)
    if not grid[0] <= x <= grid[-1]:
        return math.log(1e-300)
    return math.log(max(float(np.interp(x, grid, dens)), 1e-300))


def fit_discrepancy_exact(truths: Sequence[float], posts: Sequence[Posterior],
                          nus: Sequence[float] = NU_CHOICES) -> tuple[float, float]:
    """``(nu, sigma)`` of the coherent discrepancy by maximum likelihood on held-out objects, exactly: the
    likelihood of each true omega_n under its posterior smoothed by the discrepancy (:func:`truth_log_density`,
    the log score of the intervals the forward model will report), not under a normal approximation of the
    posterior. ``posts`` come from the forward model without its discrepancy. ``(inf, 0)`` when the posteriors
    already explain the truths."""
    from scipy.optimize import minimize_scalar

    if len(truths) != len(posts) or not posts:
        raise ValueError(f"{len(truths)} true values for {len(posts)} posteriors: need one each, at least one")

    def ll(sigma: float, nu: float) -> float:
        return float(sum(truth_log_density(p, w, sigma, nu) for w, p in zip(truths, posts, strict=True)))

    best = (ll(0.0, math.inf), math.inf, 0.0)
    for nu in nus:
        res = minimize_scalar(lambda x, nu=nu: -ll(math.exp(x), nu), bounds=(math.log(1e-3), math.log(2.0)),
                              method="bounded", options={"xatol": 1e-3})
        if -res.fun > best[0] + 1e-9:
            best = (-float(res.fun), nu, float(math.exp(res.x)))
    return best[1], best[2]


@dataclass(frozen=True)
class ModelDiscrepancy:
    """The discrepancy between a pool of models and data from a model none of them is (log omega_n): an offset
    (Student-t, scale ``offset_sigma``, ``offset_nu`` degrees of freedom), the same for every object of that
    model, plus the objects' scatter around it (Student-t, ``sigma``, ``nu``). ``pair_bias``: the mean error of
    each (data model, forward model) pair it was estimated from."""

    offset_sigma: float
    offset_nu: float
    sigma: float
    nu: float
    models: tuple[str, ...]
    pair_bias: dict = field(default_factory=dict, compare=False)

    def apply(self, fm: ForwardModel) -> ForwardModel:
        """``fm`` with this discrepancy (replacing its own)."""
        import dataclasses

        return dataclasses.replace(fm, sigma_eps=self.sigma, eps_nu=self.nu, offset_sigma=self.offset_sigma,
                                   offset_nu=self.offset_nu)

    def to_dict(self) -> dict:
        return {"offset_sigma": self.offset_sigma, "offset_nu": self.offset_nu, "sigma_eps": self.sigma,
                "eps_nu": self.nu, "models": list(self.models), "pair_bias": self.pair_bias}


def family_discrepancy(pairs: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]) -> ModelDiscrepancy:
    """The discrepancy between a pool of models and a model none of them is, from each pooled model's data
    identified by each other one (``pairs[(data, model)] = (eps, sd)``, ``eps = log(truth / estimate)`` per
    object, ``sd`` its posterior's log-sd).

    Two levels, because objects are not independent evidence about how far models lie apart: each pair's mean
    ``b`` is one draw of the offset between models (normal, variance tau^2), the objects scatter around it
    (:func:`fit_discrepancy` on the centred eps). With K models there are K - 1 independent offsets; with tau^2
    unknown (a scale-free prior) the offset of a model never seen is Student-t with K - 1 degrees of freedom and
    scale ``tau_hat = sqrt(mean b^2)`` (the offsets centred on zero: no model is the truth's). Two models give one
    degree of freedom: a Cauchy, as wide as one observed disagreement can honestly promise."""
    if not pairs:
        raise ValueError("no pairs of models to estimate a discrepancy between models from")
    models = {m for pair in pairs for m in pair}
    if len(models) < 2:
        raise ValueError(f"a discrepancy between models needs at least two models, got {sorted(models)}")
    biases = {pair: float(np.mean(eps)) for pair, (eps, _) in pairs.items() if len(eps)}
    tau = math.sqrt(float(np.mean(np.square(list(biases.values())))))
    centred = np.concatenate([np.asarray(eps, float) - biases[pair] for pair, (eps, _) in pairs.items() if len(eps)])
    sds = np.concatenate([np.asarray(sd, float) for pair, (eps, sd) in pairs.items() if len(eps)])
    nu_w, sigma_w = fit_discrepancy(centred, sds)
    return ModelDiscrepancy(offset_sigma=min(tau, 2.0), offset_nu=float(len(models) - 1), sigma=sigma_w, nu=nu_w,
                            models=tuple(sorted(models)),
                            pair_bias={f"{a}->{b}": v for (a, b), v in biases.items()})
