"""``physics="atlas"``: the response atlas of a real backend served as a physics backend.

A probe costs microseconds: omega_B is drawn from the atlas's mean and spread at (f_p, A_p, omega_n, alpha) and
the probe ends unstable (reason ``slipped``, the tile-link model's usual failure) with the atlas's instability
probability. The noise of each probe is seeded from the probe itself (its object, motion, windows and
placement), so the same probes give the same results, and a seeded environment, which draws the placement from
its own generator, gives the same episode. A yaw trace (a straight ramp at the drawn rate) is returned when asked,
so camera models work on top. Agents trained here are meant to be evaluated on the live backend.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Sequence

import numpy as np

from plate_env.core.probe import SLIPPED, ProbeRefused, ProbeResult, ProbeSpec, YawTrace, check_probes
from plate_env.physics.interface import PhysicsBackend
from plate_env.surrogate.atlas import Atlas, load_atlas


def probe_point(spec: ProbeSpec) -> dict[str, float]:
    """The quantities of a probe an atlas describes (the keywords of :meth:`Atlas.outside`), SI."""
    o, m = spec.obj, spec.motion
    return {"f_p_hz": m.freq_hz, "a_p_deg": m.a_p_deg, "omega_n": o.omega_n, "alpha": o.alpha, "b_p": m.b_p,
            "mass": o.mass, "diameter": o.diameter}


def known_input_atlases(source: str, model: str, atlas: Atlas) -> list[Atlas]:
    """The atlases of ``source``/``model`` along the known inputs: those of the shipped forward model's first member
    that include ``atlas`` (its mass axis), else ``[atlas]``."""
    from plate_env.surrogate.atlas import load_atlas_file
    from plate_env.surrogate.catalog import registry_member_atlases

    for names in registry_member_atlases(f"{source}/{model}"):
        family = [load_atlas_file(n) for n in names]
        if any(a is atlas for a in family):
            return family
    return [atlas]


class AtlasPhysics(PhysicsBackend):
    """Probes answered from the atlas of ``source``/``model`` (e.g. tilelink/pointmass).

    ``instability_rho``/``instability_corr_hz`` (domain randomisation for RL training): by default every probe's
    instability is drawn independently with the atlas's probability p. Live tile-link instability is largely set
    by the object and f_p (placement only jitters it), so with ``instability_rho`` > 0 a probe is unstable when
    Phi(rho z(f_p) + sqrt(1 - rho^2) e) < p, where z is a smooth Gaussian field along f_p (correlation length
    ``instability_corr_hz``) drawn once per object and amplitude and e a per-probe normal: each probe keeps the
    atlas's probability p, but neighbouring probes of one object agree, as live ones do.
    """

    def __init__(self, source: str = "tilelink", model: str = "pointmass", atlas: Atlas | None = None,
                 instability_rho: float = 0.0, instability_corr_hz: float = 2.0) -> None:
        if not (0.0 <= instability_rho < 1.0 and instability_corr_hz > 0):
            raise ValueError(f"instability_rho {instability_rho!r} must be in [0, 1) and instability_corr_hz "
                             f"{instability_corr_hz!r} > 0")
        self._source, self._model = source, model
        self.atlas = atlas if atlas is not None else load_atlas(source, model)
        # the atlases along the known inputs (e.g. the disc's mass) a probe is answered from, conditioned on its own
        self._family = [self.atlas] if atlas is not None else known_input_atlases(source, model, self.atlas)
        self._conditioned: dict = {}
        self.rho = instability_rho
        self.corr_hz = instability_corr_hz
        self._grid = np.arange(0.0, 60.0, 0.25)
        self._fields: dict[bytes, np.ndarray] = {}

    name = "atlas"
    SETTINGS = ("model", "rho", "corr_hz")

    @property
    def source(self) -> str:
        return self._source

    @property
    def model(self) -> str:
        return self._model

    def __repr__(self) -> str:
        return f"AtlasPhysics(source={self.source!r}, model={self.model!r})"

    @staticmethod
    def _rng(spec: ProbeSpec) -> np.random.Generator:
        o, m = spec.obj, spec.motion
        key = repr((o.omega_n, o.alpha, o.mass, m.freq_hz, m.amp_rad, m.b_p, spec.settle_s, spec.measure_s,
                    spec.initial_yaw, spec.initial_offset)).encode()
        # default_rng(seed) is Generator(PCG64(seed)): the same stream, without its dispatch
        return np.random.Generator(np.random.PCG64(int.from_bytes(hashlib.sha256(key).digest()[:8], "little")))

    def _field(self, spec: ProbeSpec) -> np.ndarray:
        """The object's smooth standard-normal field along f_p (on ``self._grid``) for correlated instability."""
        o = spec.obj
        key = repr((o.omega_n, o.alpha, o.mass, round(abs(spec.motion.a_p_deg), 6))).encode()
        if key not in self._fields:  # one per object and amplitude: an episode's probes share it
            if len(self._fields) >= 64:
                self._fields.clear()
            rng = np.random.default_rng(int.from_bytes(hashlib.sha256(key).digest()[:8], "little"))
            white = rng.normal(size=self._grid.size)
            k = np.arange(-40, 41) * 0.25
            kern = np.exp(-0.5 * (k / self.corr_hz) ** 2)
            field = np.convolve(white, kern, mode="same") / math.sqrt(np.sum(kern ** 2))
            field.flags.writeable = False
            self._fields[key] = field
        return self._fields[key]

    def _uniform(self, spec: ProbeSpec, rng: np.random.Generator) -> float:
        """The probe's U(0, 1) instability draw (independent, or correlated along f_p within the object)."""
        if self.rho == 0.0:
            return float(rng.random())
        from scipy.special import ndtr

        z = float(np.interp(spec.motion.freq_hz, self._grid, self._field(spec)))
        return float(ndtr(self.rho * z + math.sqrt(1 - self.rho ** 2) * rng.normal()))

    def atlas_for(self, spec: ProbeSpec) -> Atlas:
        """The atlas conditioned on the probe's known inputs (B_p, mass, diameter: interpolated in log mass between
        the atlases that bracket it), or the plain atlas when none is built for them (then :meth:`check` refuses)."""
        from plate_env.surrogate.conditioning import KnownInputs, condition

        key = (abs(spec.motion.b_p), spec.obj.mass, spec.obj.diameter)
        if key not in self._conditioned:
            try:
                self._conditioned[key] = (condition(self._family, KnownInputs(*key)), None)
            except ValueError as exc:  # no atlas for these inputs: check() refuses with what is available
                self._conditioned[key] = (self.atlas, str(exc))
        return self._conditioned[key][0]

    def check(self, probes: Sequence[ProbeSpec]) -> None:
        """Refuse (ProbeRefused naming the value and the atlas's range) any probe outside what the atlas describes:
        f_p, omega_n or alpha outside its grid, an amplitude it does not tabulate, or a B_p, mass or diameter no
        atlas was built at or around. The atlas would otherwise answer with a clipped or unrelated response."""
        for i, spec in enumerate(check_probes(probes)):
            atlas = self.atlas_for(spec)
            problems = atlas.outside(**probe_point(spec))
            # why no atlas answers the probe's known inputs (naming the atlases built), or None
            why = self._conditioned[(abs(spec.motion.b_p), spec.obj.mass, spec.obj.diameter)][1]
            if why is not None and "mass" in problems:  # name the masses built, not only the nearest atlas's
                problems = {**problems, "mass": why}
            if problems:
                quantity, reason = next(iter(problems.items()))
                raise ProbeRefused(quantity, f"probe {i}: {'; '.join(problems.values())} (atlas physics answers only "
                                             f"what its atlas describes; use a live backend for other probes)")

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        """Answer every probe from the atlas; refuses them all (ValueError) if one lies outside it (:meth:`check`)."""
        self.check(probes)
        out = []
        for spec in probes:
            t0 = time.perf_counter()
            rng = self._rng(spec)
            a_p_deg = spec.motion.a_p_deg
            mean, spread, p_un = self.atlas_for(spec).predict_point(spec.motion.freq_hz, abs(a_p_deg),
                                                                    spec.obj.omega_n, spec.obj.alpha)
            sign = 1.0 if spec.motion.amp_rad * spec.motion.b_p >= 0 else -1.0
            period = 1.0 / spec.motion.freq_hz
            unstable = bool(self._uniform(spec, rng) < p_un)
            if unstable:
                t_fail = float(rng.uniform(0.2, 1.0)) * spec.duration_s
                used = max(0, int(math.floor((t_fail - spec.measure_start_s) / period)))
                omega = sign * max(mean + spread * float(rng.normal()), 0.0) if used > 0 else 0.0
                sim_s = t_fail
            else:
                used = spec.n_periods
                omega = sign * (mean + spread * float(rng.normal()))
                sim_s = spec.duration_s
            se = spread / math.sqrt(max(used, 1)) if used > 0 else 0.0
            trace = None
            if spec.record_trace:
                t = np.arange(0.0, sim_s + 1e-12, 1e-3)
                # np.maximum: np.clip's floats here (t - ramp_s is never -0.0, the one value where they differ)
                yaw = np.radians(omega) * np.maximum(t - spec.motion.ramp_s, 0.0) + spec.initial_yaw
                trace = YawTrace(t=t, yaw=yaw, centre_u=np.zeros_like(t), centre_v=np.zeros_like(t))
            out.append(ProbeResult(spec=spec, omega_b_deg_s=omega if used > 0 else 0.0, stderr_deg_s=se,
                                   unstable=unstable, reason=SLIPPED if unstable else None, sim_s=sim_s,
                                   wall_s=time.perf_counter() - t0, periods_measured=used, trace=trace))
        return out
