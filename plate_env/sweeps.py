"""Run many probes with a resumable on-disk cache: every finished chunk is appended to a JSON-lines file.

Interrupting a long sweep (Ctrl-C) keeps the probes already written; running it again only simulates the rest.
Used by the experiment scripts (calibration, atlas, paper reproduction).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from plate_env.physics.base import Physics, ProbeResult, ProbeSpec

#: Backend settings that change results and so enter the cache key (each where the backend has it).
TAG_SETTINGS = ("model", "dt", "n_layer", "mesh", "config", "rigid_config", "contact", "record_interval_s")


def backend_tag(physics: Physics) -> str:
    """A string naming the backend and its settings (part of every cache key): every setting that changes a
    result (:data:`TAG_SETTINGS`: model, time step, mesh, joint and contact parameters, record interval) is in it."""
    parts = [physics.name]
    for attr in TAG_SETTINGS:
        if hasattr(physics, attr):
            parts.append(f"{attr}={getattr(physics, attr)}")
    return ",".join(parts)


def spec_key(tag: str, s: ProbeSpec) -> str:
    """A stable text key for a probe on a backend."""
    o, m = s.obj, s.motion
    nums = (o.omega_n, o.alpha, o.mass, o.diameter, o.beta, m.freq_hz, m.amp_rad, m.b_p, m.ramp_s, s.settle_s,
            s.measure_s, s.initial_yaw, *s.initial_offset)
    return tag + "|" + ",".join(repr(float(x)) for x in nums)


def _to_line(key: str, r: ProbeResult) -> str:
    return json.dumps({"key": key, "omega_b_deg_s": r.omega_b_deg_s, "stderr_deg_s": r.stderr_deg_s,
                       "unstable": r.unstable, "reason": r.reason, "sim_s": r.sim_s, "wall_s": r.wall_s,
                       "periods_measured": r.periods_measured})


def _from_record(spec: ProbeSpec, d: dict) -> ProbeResult:
    return ProbeResult(spec=spec, omega_b_deg_s=float(d["omega_b_deg_s"]), stderr_deg_s=float(d["stderr_deg_s"]),
                       unstable=bool(d["unstable"]), reason=d["reason"], sim_s=float(d["sim_s"]),
                       wall_s=float(d["wall_s"]), periods_measured=int(d["periods_measured"]))


def load_cache(path: Path) -> dict[str, dict]:
    """Read a cache file, skipping a torn last line (an interrupted write)."""
    out: dict[str, dict] = {}
    if not path.exists():
        return out
    for line in path.read_text().splitlines():
        try:
            d = json.loads(line)
            out[d["key"]] = d
        except (json.JSONDecodeError, KeyError):
            continue
    return out


def run_cached(physics: Physics, specs: Sequence[ProbeSpec], cache: str | Path | None, chunk: int = 64,
               progress: bool = True, desc: str = "probes") -> list[ProbeResult]:
    """Results for ``specs`` in order, simulating only those not yet in ``cache`` (appended chunk by chunk)."""
    tag = backend_tag(physics)
    keys = [spec_key(tag, s) for s in specs]
    done = load_cache(Path(cache)) if cache else {}
    todo = [i for i, k in enumerate(keys) if k not in done]
    bar = None
    if progress and todo:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(todo), desc=desc, unit="probe")
    fh = None
    if cache:
        Path(cache).parent.mkdir(parents=True, exist_ok=True)
        fh = open(cache, "a")  # noqa: SIM115 - kept open across chunks, closed in finally
    try:
        for start in range(0, len(todo), chunk):
            idx = todo[start:start + chunk]
            results = physics.run([specs[i] for i in idx])
            for i, r in zip(idx, results, strict=True):
                line = _to_line(keys[i], r)
                done[keys[i]] = json.loads(line)
                if fh is not None:
                    fh.write(line + "\n")
            if fh is not None:
                fh.flush()
            if bar is not None:
                bar.update(len(idx))
    finally:
        if fh is not None:
            fh.close()
        if bar is not None:
            bar.close()
    out = [_from_record(s, done[k]) for s, k in zip(specs, keys, strict=True)]
    assert all(math.isfinite(r.omega_b_deg_s) for r in out)
    return out
