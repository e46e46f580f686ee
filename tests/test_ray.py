"""The Ray executor on a local Ray with 2 CPUs: the same results as local (bit for bit, point-mass model), a killed
worker's chunk retried, an interrupted run resumed without recomputing finished chunks.

One local Ray session serves the module (~10-20 s to start on the shared 2-core machine). Marked ``ray``; skipped
when Ray is not installed (``pip install -e ".[test,ray]"``)."""

from __future__ import annotations

import os

import pytest

pytest.importorskip("ray")

from executor_helpers import (  # noqa: E402
    POINTMASS,
    Counting,
    Interrupting,
    run_killing_one,
    same,
    short_specs,
)

from plate_env.run.executor import BackendSpec, InProcessExecutor, RayExecutor, chunk_task  # noqa: E402
from plate_env.run.sweeps import load_cache, run_cached  # noqa: E402

pytestmark = pytest.mark.ray


@pytest.fixture(scope="module")
def ray_executor():
    ex = RayExecutor(num_cpus=2)
    yield ex
    ex.close()


def _descendants(pid: int) -> set[int]:
    """Process ids below ``pid`` (Linux /proc): the local Ray this test process started, and its workers."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            if c not in out:
                out.add(c)
                todo.append(c)
    return out


def _running_chunk_pids() -> list[int]:
    """Our Ray workers while they run a chunk (Ray titles a worker process ``ray::<task>`` while it runs it)."""
    pids = []
    for pid in _descendants(os.getpid()):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as fh:
                cmd = fh.read().decode(errors="replace")
        except OSError:
            continue
        if cmd.startswith("ray::run_chunk"):
            pids.append(pid)
    return pids


def test_a_ray_sweep_with_json_keeps_stdout_one_document_when_a_worker_dies(capfd):
    """Issue 28 item 17: `plate-env sweep --executor ray --json` whose Ray worker is killed mid-chunk prints strict
    JSON only on stdout, and Ray's worker-death line (which its driver thread prints to sys.stdout) on stderr.
    The sweep starts (and ends) its own Ray session, so this test runs first in the module, before the fixture's."""
    import json

    import ray

    from plate_env.cli import main

    if ray.is_initialized():
        pytest.skip("needs a Ray session of the sweep's own (runs first in this module)")

    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")

    argv = ["sweep", "--physics", "tilelink", "--object", "cheese", "--freqs", "14,16,18,20", "--settle", "0.2",
            "--measure", "30", "--chunk", "2", "--executor", "ray", "--no-progress", "--json"]
    code, killed = run_killing_one(_running_chunk_pids, lambda: main(argv))
    out, err = capfd.readouterr()
    assert killed, "no running chunk was found to kill"
    assert code == 0
    assert len(json.loads(out, parse_constant=refuse)["probes"]) == 4  # one document, nothing else
    assert "worker died" in err


def test_ray_gives_the_local_results_bit_for_bit(ray_executor):
    specs = short_specs(6, measure_s=1.0)
    local = run_cached(POINTMASS, specs, None, chunk=2, progress=False)  # the local default: in-process
    remote = run_cached(POINTMASS, specs, None, chunk=2, progress=False, executor=ray_executor)
    assert not any(r.unstable for r in local)
    assert same(local, remote)


def test_ray_retries_the_chunk_of_a_killed_worker(ray_executor, tmp_path):
    specs = short_specs(4, measure_s=30.0)  # ~0.4 s a probe: a chunk of 2 runs long enough to be killed
    reference = run_cached(POINTMASS, specs, None, chunk=2, progress=False, executor=InProcessExecutor())
    cache = tmp_path / "ray.jsonl"
    got, killed = run_killing_one(_running_chunk_pids, lambda: run_cached(POINTMASS, specs, cache, chunk=2,
                                                                          progress=False, executor=ray_executor))
    assert killed, "no running chunk was found to kill"
    assert same(got, reference)
    assert len(load_cache(cache)) == len(specs)


def test_an_interrupted_ray_run_resumes_without_recomputing(ray_executor, tmp_path):
    specs = short_specs(8)
    cache = tmp_path / "ray_resume.jsonl"
    with pytest.raises(KeyboardInterrupt):
        run_cached(POINTMASS, specs, cache, chunk=2, progress=False, executor=Interrupting(ray_executor, 2))
    kept = load_cache(cache)
    assert len(kept) == 4  # two finished chunks were written before the interrupt
    counting = Counting(ray_executor)
    resumed = run_cached(POINTMASS, specs, cache, chunk=2, progress=False, executor=counting)
    assert counting.given == [4]
    assert same(resumed, run_cached(POINTMASS, specs, None, chunk=2, progress=False))


def test_a_worker_s_error_reaches_the_caller(ray_executor):
    import ray

    with pytest.raises(ray.exceptions.RayTaskError, match="dt = -1.0"):
        list(ray_executor.map(chunk_task(BackendSpec.of("tilelink", dt=-1.0)), [short_specs(1)]))


def test_ray_workers_run_with_one_blas_and_numba_thread(ray_executor):
    import ray

    from plate_env.run.executor import WORKER_ENV

    @ray.remote(num_cpus=1)
    def env(keys):
        return [os.getenv(k) for k in keys]

    assert ray.get(env.remote(list(WORKER_ENV))) == list(WORKER_ENV.values())
