"""The executor seam (plate_env.executor) and the cached sweep that runs on it: same answers on every executor,
a dead pool worker's chunk retried, an interrupted run resumed without recomputing finished chunks.

The Ray executor's own tests are in tests/test_ray.py."""

from __future__ import annotations

import json
import os
import pickle
import sys

import pytest
from executor_helpers import (
    POINTMASS,
    Counting,
    Interrupting,
    run_killing_one,
    same,
    short_specs,
)

from plate_env.physics.tilelink.contact import PAPER_CONTACT
from plate_env.run.executor import (
    WORKER_ENV,
    BackendSpec,
    InProcessExecutor,
    PoolExecutor,
    chunk_task,
    default_local,
    make_executor,
)
from plate_env.run.executor import _env as executor_env
from plate_env.run.sweeps import load_cache, run_cached


def test_backend_spec_is_a_hashable_picklable_description():
    a = BackendSpec.of("tilelink", model="rigid_limit", contact=PAPER_CONTACT)
    b = BackendSpec.of("tilelink", contact=PAPER_CONTACT, model="rigid_limit")
    assert a == b and hash(a) == hash(b)
    assert pickle.loads(pickle.dumps(a)) == a
    phys = a.build()
    assert phys.model == "rigid_limit" and phys.contact == PAPER_CONTACT
    with pytest.raises(TypeError, match="stderr_tol_deg_s"):
        BackendSpec.of("pybullet", stderr_tol_deg_s=[1.0])


def test_make_executor_names_and_the_local_default():
    assert default_local(POINTMASS) == "inprocess"
    assert default_local(BackendSpec.of("atlas")) == "inprocess"
    assert default_local(BackendSpec.of("tilelink", model="rigid")) == "pool"
    assert default_local(BackendSpec.of("tilelink", model="rigid_limit")) == "pool"
    assert default_local(BackendSpec.of("pybullet")) == "pool"
    assert isinstance(make_executor("local", POINTMASS), InProcessExecutor)
    ex = make_executor("local", BackendSpec.of("pybullet"))
    assert isinstance(ex, PoolExecutor) and ex.workers == (os.cpu_count() or 1)
    cores = os.cpu_count() or 1
    assert make_executor(f"pool:{cores}").workers == cores  # pool:N above the CPU count: capped (issue 28)
    for bad in ("pool:0", "pool:x", "dask", "ray:/x"):
        with pytest.raises(ValueError, match="executor"):
            make_executor(bad)


def test_a_built_backend_runs_only_in_process(tilelink):
    with pytest.raises(TypeError, match="BackendSpec"):
        run_cached(tilelink, short_specs(2), None, progress=False, executor="pool:2")


def test_run_cached_results_do_not_depend_on_the_chunking_or_the_executor(tilelink):
    """Bit for bit: a built backend's direct run in this process (BLAS with all its threads), the in-process executor
    with two chunkings and a 2-process pool (workers with one BLAS thread)."""
    specs = short_specs(6, measure_s=1.0)
    direct = tilelink.run(specs)
    inproc = run_cached(POINTMASS, specs, None, chunk=6, progress=False, executor="inprocess")
    chunked = run_cached(POINTMASS, specs, None, chunk=2, progress=False, executor="inprocess")
    pooled = run_cached(POINTMASS, specs, None, chunk=2, progress=False, executor="pool:2")
    assert not any(r.unstable for r in inproc)
    assert same(direct, inproc) and same(inproc, chunked) and same(inproc, pooled)


def test_a_dead_pool_worker_s_chunk_is_retried(tmp_path):
    """SIGKILL one pool worker while chunks run: the pool breaks, the chunks not yet returned are resubmitted to a
    fresh pool, and the results equal the undisturbed run's."""
    specs = short_specs(8, measure_s=20.0)  # ~0.3 s a probe per core: chunks of 2 are in flight when killed
    reference = run_cached(POINTMASS, specs, None, chunk=2, progress=False, executor="inprocess")
    ex = PoolExecutor(workers=2)
    cache = tmp_path / "c.jsonl"
    try:
        got, killed = run_killing_one(
            lambda: ex.worker_pids() if len(ex.worker_pids()) >= 2 else [],
            lambda: run_cached(POINTMASS, specs, cache, chunk=2, progress=False, executor=ex),
            settle_s=1.0)  # workers loading the kernels / running their first chunk
    finally:
        ex.close()
    assert killed, "no worker was killed"
    assert ex.restarts >= 1
    assert same(got, reference)
    assert len(load_cache(cache)) == len(specs)


def test_a_worker_s_error_reaches_the_caller_unchanged():
    ex = PoolExecutor(workers=1)
    bad = BackendSpec.of("tilelink", dt=-1.0)  # refused by the backend's constructor, in the worker
    try:
        with pytest.raises(ValueError, match="dt = -1.0"):
            list(ex.map(chunk_task(bad), [short_specs(1)]))
        assert ex.restarts == 0  # an error is not a dead worker: no retry
    finally:
        ex.close()


def test_an_interrupted_run_resumes_without_recomputing_finished_chunks(tmp_path):
    specs = short_specs(6)
    cache = tmp_path / "sweep.jsonl"
    with pytest.raises(KeyboardInterrupt):
        run_cached(POINTMASS, specs, cache, chunk=2, progress=False, executor=Interrupting(InProcessExecutor(), 1))
    assert len(load_cache(cache)) == 2  # the finished chunk was kept
    counting = Counting(InProcessExecutor())
    resumed = run_cached(POINTMASS, specs, cache, chunk=2, progress=False, executor=counting)
    assert counting.given == [4]  # only the two unfinished chunks ran
    whole = run_cached(POINTMASS, specs, None, chunk=2, progress=False)
    assert same(resumed, whole)
    lines = cache.read_text().splitlines()
    assert len(lines) == 6 and all(json.loads(line)["key"] for line in lines)
    again = Counting(InProcessExecutor())
    run_cached(POINTMASS, specs, cache, chunk=2, progress=False, executor=again)
    assert again.given == []  # nothing left to run: the executor is not even asked


def test_import_plate_env_stays_light():
    code = "import sys, plate_env, plate_env.run.executor, plate_env.run.sweeps; print('ray' in sys.modules)"
    import subprocess

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_cli_sweep_on_an_executor_with_a_resumable_cache(tmp_path, capsys):
    from plate_env.cli import main

    base = ["sweep", "--omega-n", "10pi", "--freqs", "14:18:2", "--settle", "0.2", "--measure", "0.3", "--json",
            "--chunk", "2"]
    assert main(base) == 0
    local = json.loads(capsys.readouterr().out)["probes"]
    cache = tmp_path / "sweep.jsonl"
    assert main([*base, "--executor", "pool:2", "--cache", str(cache)]) == 0
    pooled = json.loads(capsys.readouterr().out)["probes"]
    assert [p["omega_b_deg_s"] for p in pooled] == [p["omega_b_deg_s"] for p in local]
    assert len(load_cache(cache)) == 3
    assert main([*base, "--executor", "dask"]) == 2
    assert "unknown executor 'dask'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as refused:  # refused while parsing, as every option's range (issue 16)
        main([*base, "--chunk", "0"])
    assert refused.value.code == 2 and "argument --chunk: '0' is outside the allowed range" in capsys.readouterr().err


def test_pool_workers_run_with_one_blas_and_numba_thread():
    """The workers inherit WORKER_ENV (set while they spawn); the driver's environment is restored after."""
    before = {k: os.environ.get(k) for k in WORKER_ENV}
    ex = PoolExecutor(workers=2)
    try:
        ex._pool = ex._new_pool()
        with executor_env(WORKER_ENV):
            seen = [ex._pool.submit(os.getenv, k) for k in WORKER_ENV]
        assert [f.result() for f in seen] == list(WORKER_ENV.values())
        assert {k: os.environ.get(k) for k in WORKER_ENV} == before
    finally:
        ex.close()


def test_map_is_generic_over_functions_and_items():
    """Any picklable function over any items, in-process and in a pool: no case for the executor's own tasks."""
    import math

    for name in ("inprocess", "pool:2"):
        ex = make_executor(name)
        try:
            assert sorted(ex.map(math.sqrt, [4.0, 9.0, 16.0])) == [(0, 2.0), (1, 3.0), (2, 4.0)]
        finally:
            ex.close()


def test_a_process_closes_the_backends_it_built_at_exit(tmp_path):
    """A worker owns its backends (worker_backend) and closes them when its process ends."""
    import subprocess
    import sys

    marker = tmp_path / "closed"
    code = ("import plate_env.run.executor as ex\n"
            "b = ex.worker_backend(ex.BackendSpec.of('atlas'))\n"
            f"b.close = lambda: open({str(marker)!r}, 'w').write('closed')\n"
            "print(len(ex._BACKENDS))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["1"] and marker.read_text() == "closed"
