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

from plate_env.atlas import Atlas, load_atlas
from plate_env.physics.base import SLIPPED, ProbeResult, ProbeSpec, YawTrace


class AtlasPhysics:
    """Probes answered from the atlas of ``source``/``model`` (e.g. tilelink/pointmass)."""

    def __init__(self, source: str = "tilelink", model: str = "pointmass", atlas: Atlas | None = None) -> None:
        self.name = "atlas"
        self.source = source
        self.model = model
        self.atlas = atlas if atlas is not None else load_atlas(source, model)

    def __repr__(self) -> str:
        return f"AtlasPhysics(source={self.source!r}, model={self.model!r})"

    def close(self) -> None:
        """Nothing to release."""

    @staticmethod
    def _rng(spec: ProbeSpec) -> np.random.Generator:
        o, m = spec.obj, spec.motion
        key = repr((o.omega_n, o.alpha, o.mass, m.freq_hz, m.amp_rad, m.b_p, spec.settle_s, spec.measure_s,
                    spec.initial_yaw, spec.initial_offset)).encode()
        return np.random.default_rng(int.from_bytes(hashlib.sha256(key).digest()[:8], "little"))

    def run(self, probes: Sequence[ProbeSpec], progress: bool = False) -> list[ProbeResult]:
        out = []
        for spec in probes:
            t0 = time.perf_counter()
            rng = self._rng(spec)
            a_p_deg = spec.motion.a_p_deg
            mean, spread, p_un = (float(x) for x in self.atlas.predict(spec.motion.freq_hz, abs(a_p_deg),
                                                                       spec.obj.omega_n, spec.obj.alpha))
            sign = 1.0 if spec.motion.amp_rad * spec.motion.b_p >= 0 else -1.0
            period = 1.0 / spec.motion.freq_hz
            unstable = bool(rng.random() < p_un)
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
                yaw = np.radians(omega) * np.clip(t - spec.motion.ramp_s, 0.0, None) + spec.initial_yaw
                trace = YawTrace(t=t, yaw=yaw, centre_u=np.zeros_like(t), centre_v=np.zeros_like(t))
            out.append(ProbeResult(spec=spec, omega_b_deg_s=omega if used > 0 else 0.0, stderr_deg_s=se,
                                   unstable=unstable, reason=SLIPPED if unstable else None, sim_s=sim_s,
                                   wall_s=time.perf_counter() - t0, periods_measured=used, trace=trace))
        return out
