"""One incremental posterior: a forward model's log-likelihood grids, to which probes are added one at a time.

:func:`plate_env.inference.posterior` sums each member's probe log-likelihoods and pools them
(:func:`plate_env.inference.pool`). A :class:`PosteriorState` keeps those sums: adding a probe costs one probe's
likelihood per member (independent of how many probes came before), and the posterior or the estimate after any
prefix of an episode costs one pooling (the grid's size, not the probes'). The sums are accumulated in the order
the probes arrive, exactly as the from-scratch sum does, so a state fed an episode's probes gives the same floats
as :func:`plate_env.inference.identify_atlas` of the whole table (tests/test_posterior_state.py checks this bit for
bit). Used by the env's episode end, :func:`plate_env.episode.run_episode`, the benchmark's per-prefix scores and
the bayes agent (on its own grid and blur).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.estimate import Estimate, Posterior
from plate_env.identify.forward import ForwardModel
from plate_env.identify.inference import (
    N_ALPHA,
    N_OMEGA,
    atlas_estimate,
    blurred,
    member_coverage,
    member_domain,
    member_response,
    member_rows,
    pool,
    probe_log_likelihood,
)


class PosteriorState:
    """The posterior of ``fm`` over a grid (default ``fm.grid(N_OMEGA, N_ALPHA)``), updated probe by probe.

    Args:
        fm: the forward model.
        grid: ``(omega_n rad/s, alpha rad)`` to use instead of ``fm.grid(n_omega, n_alpha)``.
        blurs: per member, the sd of log omega_n each probe's likelihood is averaged over (default each member's
            own ``blur``).
        member_rows_only: compute a member's likelihood on the grid rows inside its omega_n range only (the
            estimate's way, :func:`plate_env.inference.member_log_likelihood`); False: on the whole grid (the bayes
            agent's design grid).
        compare_on_common: members' evidences compare the probes all of them describe (the estimate's way); False:
            each member's own probes (the bayes agent's design posterior).
        finish: what the estimator does to the estimate after the posterior's own rules (``(estimate, probes) ->
            estimate``; the ``lab`` pool's readings of data of unknown origin,
            :func:`plate_env.identify.estimators.unknown_origin`), None: nothing.
    """

    def __init__(self, fm: ForwardModel, n_omega: int = N_OMEGA, n_alpha: int = N_ALPHA,
                 grid: tuple[np.ndarray, np.ndarray] | None = None, blurs: Sequence[float] | None = None,
                 member_rows_only: bool = True, compare_on_common: bool = True, extend: bool = True,
                 finish: Callable[[Estimate, ProbeTable], Estimate] | None = None) -> None:
        self.fm = fm
        self.finish = finish
        # the estimate's test beyond the identifiable range (plate_env.identify.identifiability): a state of the
        # extended model, fed this state's probes when an estimate needs it; only for the estimate's own posterior
        self._extend = extend and grid is None and blurs is None and member_rows_only and compare_on_common
        self._n_omega = int(n_omega)
        self._wide: PosteriorState | None = None
        self.omega, self.alpha = grid if grid is not None else _shared_grid(fm, n_omega, n_alpha)
        step = math.log(self.omega[1] / self.omega[0])
        blurs = [m.blur for m in fm.members] if blurs is None else list(blurs)
        if len(blurs) != len(fm.members):
            raise ValueError(f"{len(blurs)} blurs for {len(fm.members)} members: give one per member")
        self.blur_steps = [b / step for b in blurs]
        self.rows = [member_rows(m, self.omega) if member_rows_only else slice(0, len(self.omega))
                     for m in fm.members]
        self.compare_on_common = compare_on_common
        self.inside = [member_coverage(m, self.omega, self.alpha) for m in fm.members]
        shape = (len(self.omega), len(self.alpha))
        self.log_likes = [np.zeros(shape) for _ in fm.members]
        # the sums over probes every member describes: what members' evidences compare (only with several members)
        self._common = [np.zeros(shape) for _ in fm.members] if len(fm.members) > 1 else []
        self.skipped = [0] * len(fm.members)
        self.n_probes = 0
        self.n_unstable = 0
        self._orphans: set[str] = set()
        self._probes: list[tuple[float, float, float, float, bool]] = []  # for the estimate's predictive check
        self._responses: dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # this state's, for the check

    # ------------------------------------------------------------------ updates
    def add(self, f_p_hz: float, a_p_deg: float, omega_b_deg_s: float, stderr_deg_s: float, unstable: bool) -> None:
        """Add one probe (omega_B sign-normalised, deg/s; an unstable probe's omega_B is not read)."""
        f, amp = float(f_p_hz), float(a_p_deg)
        self.n_probes += 1
        self.n_unstable += int(bool(unstable))
        self._probes.append((f, amp, float(omega_b_deg_s), float(stderr_deg_s), bool(unstable)))
        reasons = [member_domain(m, f, amp) for m in self.fm.members]
        if all(r is not None for r in reasons):  # named by the last member's reason, as identify_atlas does
            self._orphans.add(str(reasons[-1]))
        common = len(reasons) > 1 and all(r is None for r in reasons)
        for i, (m, why) in enumerate(zip(self.fm.members, reasons, strict=True)):
            if why is not None:
                self.skipped[i] += 1
                continue
            rows = self.rows[i]
            sub = self.omega[rows]
            if sub.size == 0:
                continue
            mu, s, p = self.respond(m, amp, sub, self.alpha, f)
            ll = blurred(probe_log_likelihood(mu, s, p, float(omega_b_deg_s), float(stderr_deg_s), bool(unstable),
                                              m.sigma_model, m.atlas.n_repeats), self.blur_steps[i])
            self.log_likes[i][rows] += ll
            if common:
                self._common[i][rows] += ll

    def respond(self, member, a_p_deg: float, w: np.ndarray, a: np.ndarray, f_hz: float):
        """:func:`plate_env.identify.inference.respond`, the arrays of this state's probes kept (read-only): the
        estimate's predictive check reads the same responses the updates computed (one evaluation per probe)."""
        key = (id(member), abs(float(a_p_deg)), float(f_hz), len(w), float(w[0]), float(w[-1]), len(a), float(a[0]),
               float(a[-1]))
        if key not in self._responses:
            out = member_response(member, a_p_deg, w, a)[0](f_hz)
            for x in out:
                x.flags.writeable = False
            self._responses[key] = out
        return self._responses[key]

    def add_table(self, table: ProbeTable, start: int = 0) -> None:
        """Add the probes ``table[start:]`` in order."""
        for k in range(start, len(table)):
            self.add(table.f_p_hz[k], table.a_p_deg[k], table.omega_b_deg_s[k], table.stderr_deg_s[k],
                     table.unstable[k])

    # ------------------------------------------------------------------ views
    def posterior(self, discrepancy: bool = True) -> Posterior:
        """The pooled posterior of the probes so far (:func:`plate_env.inference.pool`); ``discrepancy`` False:
        without the coherent discrepancy and the offset between models (what the probes alone say)."""
        fm = self.fm if discrepancy else dataclasses.replace(self.fm, sigma_eps=0.0, offset_sigma=0.0)
        if not self.compare_on_common:
            return pool(fm, self.omega, self.alpha, self.log_likes)
        evidence = self._common if len(self.fm.members) > 1 and any(self.skipped) else None
        return pool(fm, self.omega, self.alpha, self.log_likes, self.skipped, evidence)

    def member_posteriors(self) -> tuple[np.ndarray, np.ndarray]:
        """Unsmoothed per-member posteriors (K, n_omega, n_alpha), each normalised, and the members' weights (their
        evidence x prior weight, or the prior weight alone for ``pooling="fixed"``), before any discrepancy."""
        posts, log_z = [], []
        for ll, inside, m in zip(self.log_likes, self.inside, self.fm.members, strict=True):
            ll = np.where(inside, ll, -np.inf)
            top = float(ll.max())
            like = np.exp(ll - top)
            mass = float(like.sum())
            posts.append(like / mass)
            log_z.append(top + math.log(mass) - math.log(max(int(inside.sum()), 1)) + math.log(m.weight))
        log_z = np.array(log_z)
        if self.fm.pooling == "evidence":
            wts = np.exp(log_z - log_z.max())
        else:
            wts = np.array([m.weight for m in self.fm.members], dtype=float)
        return np.array(posts), wts / wts.sum()

    def estimate(self) -> Estimate:
        """omega_n and alpha as posterior medians with equal-tailed 68 % / 95 % intervals, as
        :func:`plate_env.inference.identify_atlas` gives them (:func:`plate_env.inference.atlas_estimate`): a bound
        when the posterior piles against the edge of the identifiable range; no estimate when there are no probes or
        a probe lies outside every member's atlas (named, not dropped)."""
        cols = list(zip(*self._probes, strict=True)) if self._probes else [[]] * 5
        table = ProbeTable.from_arrays(*cols)
        est = atlas_estimate(self.fm, table, sorted(self._orphans), self.posterior, self.respond,
                             extended=self._extended())
        return est if self.finish is None else self.finish(est, table)

    def _extended(self):
        """The extended model's posterior of the probes so far, as a function (None when the model has no
        extension): its state is made once and fed the probes added since it last answered."""
        if not self._extend:
            return None
        if self._wide is None:
            from plate_env.identify.identifiability import extended_model

            wide = extended_model(self.fm)
            if wide is None:
                self._extend = False
                return None
            self._wide = PosteriorState(wide, n_omega=self._n_omega,
                                        n_alpha=len(self.alpha), extend=False)
        state = self._wide

        def post() -> Posterior:
            for probe in self._probes[state.n_probes:]:
                state.add(*probe)
            return state.posterior()

        return post

    def prefix_estimates(self, table: ProbeTable) -> tuple[Estimate, ...]:
        """Add ``table``'s probes one by one; the estimate after each (an episode's estimates as it went)."""
        out = []
        for k in range(len(table)):
            self.add_table(table.subset(np.arange(len(table)) == k))
            out.append(self.estimate())
        return tuple(out)


#: ``fm.grid(n_omega, n_alpha)`` per forward model (kept with the model: an id is only unique while it lives).
_GRIDS: dict[tuple[int, int, int], tuple[ForwardModel, tuple[np.ndarray, np.ndarray]]] = {}


def _shared_grid(fm: ForwardModel, n_omega: int, n_alpha: int) -> tuple[np.ndarray, np.ndarray]:
    """``fm.grid(n_omega, n_alpha)`` computed once per forward model and shared (read-only) by its states: an env
    makes a state per episode."""
    key = (id(fm), int(n_omega), int(n_alpha))
    hit = _GRIDS.get(key)
    if hit is None or hit[0] is not fm:
        if len(_GRIDS) >= 32:
            _GRIDS.clear()
        w, a = fm.grid(n_omega, n_alpha)
        w.flags.writeable = False
        a.flags.writeable = False
        hit = _GRIDS[key] = (fm, (w, a))
    return hit[1]
