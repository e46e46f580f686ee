"""Where batches of probes run: one executor seam for sweeps, atlases, calibrations and benchmark suites.

An executor is generic: ``executor.map(fn, items)`` yields ``(index, fn(item))`` as items finish, ``fn`` a picklable
callable (a module-level function, or a :func:`functools.partial` of one) for executors with workers. For probes the
item is a *chunk*, a list of :class:`ProbeSpec`, and ``fn`` is :func:`chunk_task` of a :class:`BackendSpec`, the
picklable description of a backend (``make_physics`` name and options); the benchmark maps whole episodes the same
way. A process builds a backend once (:func:`worker_backend`) and keeps it for every later chunk of the same
description (numba's kernels load once per worker, a PyBullet worker keeps its client and builds a
scene per object sequence of the chunk) and returns the chunk's :class:`ProbeResult` list. Executors yield finished
chunks as they complete (in any order); :func:`plate_env.run.sweeps.run_cached` persists each one on arrival, so a
killed driver or worker loses at most the chunks in flight.

Executors (:func:`make_executor`):

* ``"local"`` (default): ``"inprocess"`` for the tile-link point-mass model and the atlas (numba already spreads a
  batch over the cores), ``"pool"`` for PyBullet and the rigid tile models.
* ``"inprocess"``: chunks run one after another in this process.
* ``"pool"`` / ``"pool:N"``: a spawned process pool (N workers, default one per core); a chunk whose worker died is
  resubmitted to a fresh pool (at most ``max_retries`` times).
* ``"ray"``: Ray tasks (``pip install "plate-env[ray]"``): joins the cluster named by ``RAY_ADDRESS`` (as set by
  ``ray job submit``) or one started with ``ray start``, else starts a local one; ``"ray://HOST:PORT"``: a Ray
  cluster through Ray Client. Ray retries a chunk whose worker died (``max_retries``). Ray is imported only here.

Workers run with one BLAS and one numba thread (``WORKER_ENV``): one chunk per core.

Determinism: a chunk's results depend only on its probes and its backend description, not on the executor, the
process or the other chunks: bit for bit (tests/test_executor.py, tests/test_ray.py). Two facts make that hold: the
point-mass builders hold BLAS to one thread (their eigensolve's last bits depend on the BLAS thread count, grown by
the kernel to ~1e-10 of omega_B), and a process that compiles the kernels runs the same code as one that loads them
from numba's disk cache (README, Determinism).
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import os
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from plate_env.physics import Physics, ProbeResult, ProbeSpec, make_physics

#: Environment of every pool / Ray worker: one thread for numpy's BLAS (its spinning threads cost ~3.5 % of a
#: PyBullet step) and for numba (one chunk per core).
WORKER_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
#: Executor names accepted by :func:`make_executor` (plus ``pool:N`` and ``ray://HOST:PORT``).
EXECUTOR_NAMES = ("local", "inprocess", "pool", "ray")
#: tilelink models that run in a process pool under the ``local`` executor.
POOLED_TILELINK_MODELS = ("rigid", "rigid_limit", "rigid_fast")


@dataclass(frozen=True)
class BackendSpec:
    """A picklable, hashable description of a backend: ``make_physics(name, **dict(options))``.

    Build with :meth:`of`: ``BackendSpec.of("tilelink", model="rigid_limit", contact=ContactLaw(...))``. Option values
    must be hashable (frozen dataclasses, numbers, strings, tuples).
    """

    name: str
    options: tuple[tuple[str, Any], ...] = ()

    @classmethod
    def of(cls, name: str, **options: Any) -> BackendSpec:
        spec = cls(name, tuple(sorted(options.items())))
        try:
            hash(spec)
        except TypeError:
            bad = [k for k, v in options.items() if not _hashable(v)]
            raise TypeError(f"backend options {bad} must be hashable (use tuples, frozen dataclasses)") from None
        return spec

    def build(self) -> Physics:
        """A fresh backend (the caller closes it)."""
        return make_physics(self.name, **dict(self.options))

    def option(self, key: str, default: Any = None) -> Any:
        return dict(self.options).get(key, default)


def _hashable(v: Any) -> bool:
    try:
        hash(v)
    except TypeError:
        return False
    return True


# --------------------------------------------------------------------------- the worker side
#: Backends built in this process, by description (a worker keeps a few; the oldest is closed beyond that).
_BACKENDS: dict[BackendSpec, Physics] = {}
_MAX_BACKENDS = 4


def close_backends() -> None:
    """Close every backend this process built (:func:`worker_backend`); run at the process's exit, so a worker (a
    pool's, Ray's, or this process) closes what it owns: PyBullet clients, numba thread pools."""
    while _BACKENDS:
        _BACKENDS.popitem()[1].close()


def worker_backend(backend: BackendSpec) -> Physics:
    """This process's backend for ``backend``: built on first use, then reused; closed at the process's exit (or
    when more than a few are kept, the oldest first)."""
    phys = _BACKENDS.get(backend)
    if phys is None:
        if not _BACKENDS:
            atexit.unregister(close_backends)
            atexit.register(close_backends)
        if len(_BACKENDS) >= _MAX_BACKENDS:
            old = next(iter(_BACKENDS))
            _BACKENDS.pop(old).close()
        phys = _BACKENDS[backend] = backend.build()
    return phys


def run_chunk(backend: BackendSpec, probes: Sequence[ProbeSpec]) -> list[ProbeResult]:
    """Run one chunk of probes on this process's backend for ``backend``."""
    return worker_backend(backend).run(list(probes))


def chunk_task(backend: BackendSpec) -> Callable[[Sequence[ProbeSpec]], list[ProbeResult]]:
    """The picklable ``fn`` that runs a chunk of probes on ``backend`` for :meth:`Executor.map`."""
    return functools.partial(run_chunk, backend)


# --------------------------------------------------------------------------- executors
class Executor(Protocol):
    """Runs ``fn`` on items and yields ``(item index, fn(item))`` as items finish."""

    name: str

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """Every item's result, in completion order. Closing the iterator early (Ctrl-C, an error in the consumer)
        cancels the items not yet finished. ``fn`` must pickle for executors with workers (a module-level function
        or a :func:`functools.partial` of one: :func:`chunk_task` for probes)."""
        ...

    def close(self) -> None:
        """Release workers (processes, a Ray session this executor started). Safe to call twice."""
        ...


class InProcessExecutor:
    """Items one after another in this process (``fn`` need not pickle: a built backend's ``run`` will do). Numba's
    threads are not limited here (the point-mass kernel spreads a chunk over the cores)."""

    name = "inprocess"

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        for i, item in enumerate(items):
            yield i, fn(item)

    def close(self) -> None:
        """Nothing to release (backends built here are this process's, closed at its exit)."""


@contextlib.contextmanager
def _env(values: dict[str, str]):
    """``os.environ`` updated while the block runs (spawned children inherit it), restored after."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class PoolExecutor:
    """A spawned process pool; each worker keeps its backends between chunks.

    A worker that dies (killed, out of memory) breaks the pool: the chunks not yet returned are resubmitted to a
    fresh pool, at most ``max_retries`` times each, then :class:`RuntimeError`.
    """

    name = "pool"

    def __init__(self, workers: int | None = None, max_retries: int = 3) -> None:
        if workers is None:
            workers = os.cpu_count() or 1
        if not (isinstance(workers, int) and workers >= 1):
            raise ValueError(f"pool workers = {workers!r} must be a positive int")
        self.workers = workers
        self.max_retries = max_retries
        self.restarts = 0  #: pools replaced after a worker died
        self._pool = None

    def _new_pool(self):
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        return ProcessPoolExecutor(max_workers=self.workers, mp_context=mp.get_context("spawn"),
                                   initializer=ignore_interrupts)

    def _terminate(self) -> None:
        """Ctrl-C: end the workers now (they ignore SIGINT, so none prints a traceback) and drop the pool."""
        if self._pool is None:
            return
        for proc in list((getattr(self._pool, "_processes", None) or {}).values()):
            with contextlib.suppress(Exception):
                proc.terminate()
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._pool = None

    def worker_pids(self) -> list[int]:
        """Process ids of the live workers (for fault tests)."""
        procs = getattr(self._pool, "_processes", None) or {}
        return [p.pid for p in procs.values() if p.is_alive()]

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        from concurrent.futures.process import BrokenProcessPool

        pending = list(range(len(items)))
        failures = dict.fromkeys(pending, 0)
        while pending:
            if self._pool is None:
                self._pool = self._new_pool()
            futures: dict = {}
            try:
                with _env(WORKER_ENV):  # workers spawn during submit and inherit this environment
                    for i in pending:  # a Ctrl-C may land here too (spawning is slow on a busy machine)
                        futures[self._pool.submit(fn, items[i])] = i
                for fut in _completed(futures):
                    i = futures[fut]
                    res = fut.result()
                    pending.remove(i)
                    yield i, res
            except KeyboardInterrupt:
                self._terminate()
                raise
            except BrokenProcessPool:
                self._pool.shutdown(wait=False, cancel_futures=True)
                self._pool = None
                self.restarts += 1
                for i in pending:
                    failures[i] += 1
                worst = max(pending, key=failures.__getitem__)
                if failures[worst] > self.max_retries:
                    raise RuntimeError(f"item {worst} lost its worker {failures[worst]} times; giving up") from None
            finally:
                if pending and self._pool is not None:
                    for fut in futures:
                        fut.cancel()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


#: How often (s) a pool's driver wakes while it waits for chunks, to see a Ctrl-C.
POLL_S = 0.2


def _completed(futures: dict) -> Iterator:
    """``concurrent.futures.as_completed``, waking every :data:`POLL_S` s. The kernel hands a Ctrl-C to any thread of
    this process that does not block it (the pool's manager thread, a BLAS or numba thread): a wait without a
    timeout then blocks the main thread in C, where Python cannot run its handler, until a chunk ends. Futures done
    together come in submission order."""
    from concurrent.futures import FIRST_COMPLETED, wait

    left = set(futures)
    while left:
        done, left = wait(left, timeout=POLL_S, return_when=FIRST_COMPLETED)
        yield from sorted(done, key=futures.__getitem__)


def ignore_interrupts() -> None:
    """A pool worker's initializer: Ctrl-C reaches the whole process group, and the driver alone handles it (it
    keeps the finished chunks and ends the workers); a worker would print its own KeyboardInterrupt traceback."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


class RayExecutor:
    """Chunks as Ray tasks (``num_cpus=1`` each, retried ``max_retries`` times when their worker dies).

    ``address``: None joins the cluster named by ``RAY_ADDRESS`` or a running ``ray start`` head, else starts a local
    Ray (``num_cpus`` CPUs, default all); ``"ray://HOST:PORT"`` connects through Ray Client (driver here, workers
    there: the cluster's nodes need plate-env installed at the same version). A Ray session this executor started is
    shut down by :meth:`close`. At most ``max_in_flight`` chunks are submitted at once (default 2 per cluster CPU).
    """

    name = "ray"

    def __init__(self, address: str | None = None, num_cpus: int | None = None, max_retries: int = 3,
                 max_in_flight: int | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise ImportError('the ray executor needs Ray: pip install "plate-env[ray]"') from None
        self._ray = ray
        self._owns = False
        if not ray.is_initialized():
            kw: dict[str, Any] = {"runtime_env": {"env_vars": dict(WORKER_ENV)}, "log_to_driver": False}
            if address is None and not os.environ.get("RAY_ADDRESS"):
                kw.update(num_cpus=num_cpus, include_dashboard=False, object_store_memory=200 * 2**20)
            ray.init(address=address, **kw)
            self._owns = True
        self._max_retries = max_retries
        self._tasks: dict[Callable, Any] = {}
        cpus = int(ray.cluster_resources().get("CPU", 1))
        self.max_in_flight = max_in_flight or 2 * max(cpus, 1)

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        ray = self._ray
        # a partial runs as a task of its function (named after it, ``ray::run_chunk``), its arguments put once
        func, args = (fn.func, fn.args) if isinstance(fn, functools.partial) and not fn.keywords else (fn, ())
        if func not in self._tasks:
            self._tasks[func] = ray.remote(num_cpus=1, max_retries=self._max_retries)(func)
        remote = self._tasks[func]
        arg_refs = [ray.put(a) for a in args]
        pending = deque(range(len(items)))
        refs: dict[Any, int] = {}
        try:
            while pending or refs:
                while pending and len(refs) < self.max_in_flight:
                    i = pending.popleft()
                    refs[remote.remote(*arg_refs, items[i])] = i
                ready, _ = ray.wait(list(refs), num_returns=1)
                for ref in ready:
                    i = refs.pop(ref)
                    yield i, ray.get(ref)
        finally:
            for ref in refs:
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)

    def close(self) -> None:
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
        self._owns = False


def default_local(backend: BackendSpec) -> str:
    """What ``"local"`` means for a backend: ``"pool"`` for PyBullet and the rigid tile models, else ``"inprocess"``."""
    if backend.name == "pybullet" or (backend.name == "tilelink" and backend.option("model") in POOLED_TILELINK_MODELS):
        return "pool"
    return "inprocess"


def check_executor_name(name: str | None) -> None:
    """Refuse an executor name :func:`make_executor` would not accept (ValueError naming it), starting nothing.
    None is the default (``local``); an empty name is refused, not read as the default."""
    name = "local" if name is None else name
    if name in EXECUTOR_NAMES or name.startswith("ray://"):
        return
    if name.startswith("pool:"):
        n = name.split(":", 1)[1]
        if n.isascii() and n.isdigit() and int(n) >= 1:  # ASCII digits only: "²".isdigit() is True
            return
        raise ValueError(f"executor {name!r}: pool:N needs a positive number of workers N")
    raise ValueError(f"unknown executor {name!r}; choose local, inprocess, pool, pool:N, ray or ray://HOST:PORT")


def pool_workers(name: str) -> int | None:
    """The workers of ``pool:N``: N, at most the CPU count (more only queue for the same cores and cost a process
    each; a warning says so); None for ``pool`` (one per core)."""
    if ":" not in name:
        return None
    n = int(name.split(":", 1)[1])
    cores = os.cpu_count() or 1
    if n > cores:
        import warnings

        warnings.warn(f"executor {name!r}: {n} workers on {cores} CPU cores; using {cores} (more would only wait for "
                      "the same cores)", stacklevel=3)
        return cores
    return n


def make_executor(name: str | None = "local", backend: BackendSpec | None = None, **kw: Any) -> Executor:
    """An executor by name: ``local`` (default, by backend), ``inprocess``, ``pool[:N]``, ``ray`` or
    ``ray://HOST:PORT``; ``kw`` go to its constructor. Refuses an unknown name before any work starts."""
    check_executor_name(name)
    name = "local" if name is None else name
    if name == "local":
        name = default_local(backend) if backend is not None else "inprocess"
    if name == "inprocess":
        return InProcessExecutor(**kw)
    if name == "pool" or name.startswith("pool:"):
        return PoolExecutor(workers=pool_workers(name), **kw)
    if name.startswith("ray://"):
        return RayExecutor(address=name, **kw)
    return RayExecutor(**kw)


def add_executor_argument(parser) -> None:
    """The ``--executor`` option of the CLI and the experiment scripts."""
    parser.add_argument("--executor", default="local",
                        help="where chunks of probes run: local (default: in-process for the point-mass model, a "
                             "process pool for pybullet and rigid tiles), inprocess, pool, pool:N, ray (local Ray or "
                             "the cluster in RAY_ADDRESS) or ray://HOST:PORT")
