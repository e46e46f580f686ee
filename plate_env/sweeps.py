"""Run many probes with a resumable on-disk cache: every finished chunk is appended to a JSON-lines file.

Interrupting a long sweep (Ctrl-C) keeps the probes already written; running it again only simulates the rest.
Used by the experiment scripts (calibration, atlas, paper reproduction).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Sequence
from pathlib import Path

from plate_env.physics.base import Physics, ProbeResult, ProbeSpec

#: Probes per backend call when results are wanted as they finish (the tile-link batch keeps both cores busy).
CHUNK = 8


def backend_tag(physics: Physics) -> str:
    """A string naming the backend and its settings (part of every cache key)."""
    parts = [physics.name]
    for attr in ("model", "dt", "n_layer", "mesh"):
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


def chunk_size(physics: Physics) -> int:
    """Probes per call for results as they finish: :data:`CHUNK`, or a process pool's worth of PyBullet units."""
    return max(CHUNK, getattr(physics, "n_workers", 1) * getattr(physics, "sequence_len", 1))


def run_chunks(physics: Physics, specs: Sequence[ProbeSpec], chunk: int, progress: bool = True,
               desc: str = "probes") -> Iterator[list[ProbeResult]]:
    """Run ``specs`` in order, ``chunk`` probes per backend call, yielding each chunk's results as it finishes
    (with a progress bar if asked). An interrupt (Ctrl-C) propagates from the chunk that was running; the chunks
    already yielded are the caller's to keep (printed, cached)."""
    specs = list(specs)
    bar = None
    if progress and specs:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(specs), desc=desc, unit="probe")
    try:
        for start in range(0, len(specs), chunk):
            part = physics.run(specs[start:start + chunk])
            if bar is not None:
                bar.update(len(part))
            yield part
    finally:
        if bar is not None:
            bar.close()


def _open_for_append(path: Path):
    """``path`` opened for appending (binary), after cutting off a torn last line (an interrupted write), so the
    next record starts on a line of its own instead of completing the fragment into an invalid line."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = path.read_bytes() if path.exists() else b""
    if data and not data.endswith(b"\n"):
        with open(path, "r+b") as fh:
            fh.truncate(data.rfind(b"\n") + 1)
    return open(path, "ab")  # noqa: SIM115 - returned to the caller, who closes it


def run_cached(physics: Physics, specs: Sequence[ProbeSpec], cache: str | Path | None, chunk: int = 64,
               progress: bool = True, desc: str = "probes") -> list[ProbeResult]:
    """Results for ``specs`` in order, simulating only those not yet in ``cache`` (appended chunk by chunk)."""
    tag = backend_tag(physics)
    keys = [spec_key(tag, s) for s in specs]
    done = load_cache(Path(cache)) if cache else {}
    todo = [i for i, k in enumerate(keys) if k not in done]
    fh = _open_for_append(Path(cache)) if cache else None
    try:
        finished = 0
        for results in run_chunks(physics, [specs[i] for i in todo], chunk, progress, desc):
            idx = todo[finished:finished + len(results)]
            finished += len(results)
            for i, r in zip(idx, results, strict=True):
                line = _to_line(keys[i], r)
                done[keys[i]] = json.loads(line)
                if fh is not None:
                    fh.write((line + "\n").encode())
            if fh is not None:
                fh.flush()
    finally:
        if fh is not None:
            fh.close()
    out = [_from_record(s, done[k]) for s, k in zip(specs, keys, strict=True)]
    assert all(math.isfinite(r.omega_b_deg_s) for r in out)
    return out
