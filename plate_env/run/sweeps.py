"""Run many probes with a resumable on-disk cache: every finished chunk is appended to a JSON-lines file.

Interrupting a long sweep (Ctrl-C) keeps the probes already written; running it again only simulates the rest.
Chunks run on an executor (:mod:`plate_env.run.executor`: in-process, a process pool or Ray) and are written as they
finish, in any order. Used by the CLI's ``sweep`` and the experiment scripts (calibration, atlas, paper reproduction).
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Sequence
from pathlib import Path

from plate_env.core.files import check_regular
from plate_env.core.probe import SLIP_LIMIT_M, ProbeResult, ProbeSpec
from plate_env.physics.interface import Physics
from plate_env.run.executor import (
    BackendSpec,
    Executor,
    InProcessExecutor,
    check_executor_name,
    chunk_task,
    make_executor,
)

#: Backend settings that change results and so enter the cache key (each where the backend has it).
TAG_SETTINGS = ("model", "dt", "n_layer", "mesh", "config", "rigid_config", "contact", "record_interval_s",
                "slip_limit", "k_elastic", "stderr_tol_deg_s", "rho", "corr_hz", "kernel")
#: Settings named in the key only when they differ from this default: they became options after caches of the
#: default existed, which stay valid (tilelink ``slip_limit`` and ``kernel``, pybullet ``k_elastic`` and
#: ``stderr_tol_deg_s``, the atlas's ``instability_rho`` and ``instability_corr_hz``, kept as ``rho`` and ``corr_hz``).
TAG_DEFAULTS = {"record_interval_s": 1e-3, "slip_limit": SLIP_LIMIT_M, "k_elastic": None, "stderr_tol_deg_s": None,
                "rho": 0.0, "corr_hz": 2.0, "kernel": "v1"}


def backend_tag(physics: Physics | BackendSpec) -> str:
    """A string naming the backend and its settings (part of every cache key): every setting that changes a
    result (the ``settings`` of the backend's ``describe()``, in :data:`TAG_SETTINGS`' order: model, time step, mesh,
    joint and contact parameters, record interval) is in it (those of :data:`TAG_DEFAULTS` only when they differ
    from it); a setting :data:`TAG_SETTINGS` does not list is refused (ValueError). A :class:`BackendSpec` is built
    (cheaply: no client or kernel is touched) to read them."""
    if isinstance(physics, BackendSpec):
        built = physics.build()
        try:
            return backend_tag(built)
        finally:
            built.close()
    d = physics.describe()
    settings = d["settings"]
    unknown = set(settings) - set(TAG_SETTINGS)
    if unknown:  # a setting the key would not name: two backends differing in it would share cached results
        raise ValueError(f"{d['name']} declares settings {sorted(unknown)} that plate_env.run.sweeps.TAG_SETTINGS "
                         "does not list")
    parts = [d["name"]]
    for attr in TAG_SETTINGS:
        if attr in settings and not (attr in TAG_DEFAULTS and settings[attr] == TAG_DEFAULTS[attr]):
            parts.append(f"{attr}={settings[attr]}")
    return ",".join(parts)


#: Significant digits of a probe's numbers in its key. A value drawn or derived with numpy's vectorised exp/log
#: may differ in its last bit between CPUs (64.75698404964186 here, ...187 on an AVX-512 machine): 12 digits keep
#: keys equal across machines (a 1-ulp change crosses a 12-digit rounding boundary about once in 10^4 numbers)
#: while telling apart any two probes a grid or a prior draw makes.
KEY_DIGITS = 12


def _key_number(x: float) -> str:
    return repr(float(f"{float(x):.{KEY_DIGITS}g}"))


def spec_key(tag: str, s: ProbeSpec) -> str:
    """A stable text key for a probe on a backend: the backend's tag, then the probe's numbers (SI) at
    :data:`KEY_DIGITS` significant digits, so the same probe has the same key on any CPU."""
    o, m = s.obj, s.motion
    nums = (o.omega_n, o.alpha, o.mass, o.diameter, o.beta, m.freq_hz, m.amp_rad, m.b_p, m.ramp_s, s.settle_s,
            s.measure_s, s.initial_yaw, *s.initial_offset)
    return tag + "|" + ",".join(_key_number(x) for x in nums)


def canonical_key(key: str) -> str:
    """``key`` as :func:`spec_key` writes it today: caches written before keys were rounded (full ``repr`` of each
    number) are read through this, so their records still match. A key that is not of that form is returned as is."""
    tag, sep, rest = key.rpartition("|")
    if not sep:
        return key
    try:
        return tag + "|" + ",".join(_key_number(float(x)) for x in rest.split(","))
    except ValueError:
        return key


def _to_line(key: str, r: ProbeResult) -> str:
    return json.dumps({"key": key, "omega_b_deg_s": r.omega_b_deg_s, "stderr_deg_s": r.stderr_deg_s,
                       "unstable": r.unstable, "reason": r.reason, "sim_s": r.sim_s, "wall_s": r.wall_s,
                       "periods_measured": r.periods_measured})


def result_from_record(spec: ProbeSpec, d: dict) -> ProbeResult:
    """The :class:`ProbeResult` of ``spec`` from its cache record ``d`` (a line of a sweep cache, as
    :func:`load_cache` returns them): omega_B and its standard error in deg/s, simulated and wall time in s."""
    return ProbeResult(spec=spec, omega_b_deg_s=float(d["omega_b_deg_s"]), stderr_deg_s=float(d["stderr_deg_s"]),
                       unstable=bool(d["unstable"]), reason=d["reason"], sim_s=float(d["sim_s"]),
                       wall_s=float(d["wall_s"]), periods_measured=int(d["periods_measured"]))


def check_cache_file(path: Path, option: str = "--cache") -> Path:
    """``path`` if it is a regular file or does not exist yet, else ValueError naming it: a device (``/dev/zero``
    reads forever), a FIFO (blocks) or a directory is never a cache."""
    return check_regular(path, option, missing_ok=True)


def numbered_records(path: Path):
    """``(line number, object)`` of a JSON-lines file (none if it does not exist), skipping a torn last line (an
    interrupted write) and lines that are not objects; refuses a path that is not a regular file."""
    if not check_cache_file(path).exists():
        return
    for lineno, line in enumerate(path.read_text().splitlines(), start=1):
        try:
            d = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(d, dict):
            yield lineno, d


def read_records(path: Path) -> list[dict]:
    """The JSON objects of a JSON-lines file (none if it does not exist), skipping a torn last line (an
    interrupted write) and lines that are not objects. ValueError if ``path`` is not a regular file."""
    return [d for _, d in numbered_records(Path(path))]


def number_problem(name: str, v, lo: float = -math.inf, integral: bool = False) -> str | None:
    """Why the JSON value ``v`` of field ``name`` is not a finite number >= ``lo`` (an integer if ``integral``;
    JSON's NaN, Infinity, null, strings and booleans are not), else None."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integral and not isinstance(v, int)):
        return f"{name} = {v!r} is not {'an integer' if integral else 'a number'}"
    if not (math.isfinite(v) and v >= lo):
        return f"{name} = {v!r} is outside [{lo:g}, inf)"
    return None


def record_problem(d: dict) -> str | None:
    """Why a sweep-cache record cannot be loaded (a field missing, of the wrong type or out of range), else None."""
    def number(name: str, lo: float = -math.inf, integral: bool = False) -> str | None:
        return number_problem(name, d.get(name), lo, integral)

    for problem in (number("omega_b_deg_s"), number("stderr_deg_s", 0.0), number("sim_s", 0.0),
                    number("wall_s", 0.0), number("periods_measured", 0, integral=True)):
        if problem:
            return problem
    if not isinstance(d.get("unstable"), bool):
        return f"unstable = {d.get('unstable')!r} is not true/false"
    if not (d.get("reason") is None or isinstance(d.get("reason"), str)):
        return f"reason = {d.get('reason')!r} is not a string or null"
    return None


def load_cache(path: Path) -> dict[str, dict]:
    """A sweep cache file's records by key (torn or foreign lines skipped). A record with a bad field is skipped
    with a warning naming the file, line and field (its probe runs again), never loaded."""
    import warnings

    out = {}
    for lineno, d in numbered_records(Path(path)):
        if "key" not in d:
            continue
        problem = record_problem(d)
        if problem:
            warnings.warn(f"{path}: line {lineno}: {problem}; the record is skipped (its probe runs again)",
                          stacklevel=2)
            continue
        out[canonical_key(d["key"])] = d
    return out


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`run_cached`: ``results`` are the probes finished by then (this run's chunks and those
    found in the cache), in the order of the specs, so a caller can print them before it exits."""

    def __init__(self, results: list[ProbeResult]) -> None:
        super().__init__()
        self.results = results


def open_for_append(path: Path):
    """``path`` opened for appending (binary), after cutting off a torn last line (an interrupted write), so the
    next record starts on a line of its own instead of completing the fragment into an invalid line."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = path.read_bytes() if path.exists() else b""
    if data and not data.endswith(b"\n"):
        with open(path, "r+b") as fh:
            fh.truncate(data.rfind(b"\n") + 1)
    return open(path, "ab")  # noqa: SIM115 - returned to the caller, who closes it


def _cache_failed(cache, exc: OSError) -> None:
    import warnings

    warnings.warn(f"cannot write the cache {str(cache)!r} ({exc.strerror or exc}): the sweep goes on without it and "
                  "its probes are returned (printed) all the same; a rerun recomputes what was not written (a torn "
                  "last line is skipped)", stacklevel=3)


def run_cached(physics: Physics | BackendSpec, specs: Sequence[ProbeSpec], cache: str | Path | None,
               chunk: int = 64, progress: bool = True, desc: str = "probes",
               executor: Executor | str | None = None) -> list[ProbeResult]:
    """Results for ``specs`` in order, simulating only those not yet in ``cache`` (appended chunk by chunk).

    Chunks are cut from the whole ``specs`` list every ``chunk`` probes (so an interrupted and resumed run runs the
    same chunks, less the finished ones; a chunk is a PyBullet object sequence's boundary) and run on ``executor``
    (an :class:`~plate_env.run.executor.Executor` or a name for :func:`~plate_env.run.executor.make_executor`; default
    ``"local"``), each written to the cache and counted on the progress bar as it finishes. ``physics`` is a
    :class:`BackendSpec` (any executor) or a built backend (in this process only).
    """
    if not (isinstance(chunk, int) and chunk >= 1):
        raise ValueError(f"chunk = {chunk!r} must be a positive int")
    tag = backend_tag(physics)
    keys = [spec_key(tag, s) for s in specs]
    done = load_cache(Path(cache)) if cache else {}
    chunks = [[i for i in range(start, min(start + chunk, len(specs))) if keys[i] not in done]
              for start in range(0, len(specs), chunk)]
    chunks = [c for c in chunks if c]
    own = executor is None or isinstance(executor, str)  # an executor object passed in stays the caller's
    if isinstance(physics, BackendSpec):
        backend, fn = physics, chunk_task(physics)
        if own:
            check_executor_name(executor)
            executor = make_executor(executor, backend) if chunks else None  # workers only if there is work
    else:
        fn = physics.run
        if executor not in (None, "local", "inprocess"):
            raise TypeError(f"executor {executor!r} needs a BackendSpec (a built {physics.name} backend cannot be "
                            "sent to workers): pass BackendSpec.of(name, **options)")
        executor, own = InProcessExecutor(), True
    bar = None
    if progress and chunks:
        from plate_env.core.progress import progress_bar

        bar = progress_bar(sum(map(len, chunks)), desc, "probe")
    fh = None
    if cache and chunks:
        try:
            fh = open_for_append(Path(cache))
        except OSError as exc:
            _cache_failed(cache, exc)
    try:
        if chunks:
            for j, results in executor.map(fn, [[specs[i] for i in c] for c in chunks]):
                idx = chunks[j]
                lines = []
                for i, r in zip(idx, results, strict=True):
                    line = _to_line(keys[i], r)
                    done[keys[i]] = json.loads(line)
                    lines.append(line + "\n")
                if fh is not None:
                    try:
                        fh.write("".join(lines).encode())
                        fh.flush()
                    except OSError as exc:  # disk full, quota, I/O error: the sweep goes on, its results in memory
                        _cache_failed(cache, exc)
                        with contextlib.suppress(OSError):
                            fh.close()
                        fh = None
                if bar is not None:
                    bar.update(len(idx))
    except KeyboardInterrupt:
        raise SweepInterrupted([result_from_record(s, done[k]) for s, k in zip(specs, keys, strict=True)
                                if k in done]) from None
    finally:
        if own and executor is not None:
            executor.close()
        if fh is not None:
            with contextlib.suppress(OSError):
                fh.close()
        if bar is not None:
            bar.close()
    out = [result_from_record(s, done[k]) for s, k in zip(specs, keys, strict=True)]
    assert all(math.isfinite(r.omega_b_deg_s) for r in out)
    return out
