"""The disk cache of spline coefficients: cached results equal fresh ones bit for bit, other inputs never hit an
entry made from different ones (a stale entry is never used), an unreadable entry is rebuilt, ``off`` writes none."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from plate_env.core.cache import cache_dir, content_key
from plate_env.surrogate.atlas import Atlas, load_atlas_file


def _fresh(atlas: Atlas) -> Atlas:
    """The same arrays in a new instance (its in-memory interpolators empty)."""
    return dataclasses.replace(atlas)


@pytest.fixture
def atlas() -> Atlas:
    return _fresh(load_atlas_file("atlas_tilelink_rigid_limit_f2.npz"))


def _points(atlas: Atlas, n: int = 50):
    rng = np.random.default_rng(0)
    return (rng.uniform(atlas.f_hz[0], atlas.f_hz[-1], n),
            np.exp(rng.uniform(math.log(atlas.omega_n[0]), math.log(atlas.omega_n[-1]), n)),
            rng.uniform(atlas.alpha[0], atlas.alpha[-1], n))


def test_cached_atlas_spline_equals_scipys_interpolator(atlas, tmp_path, monkeypatch):
    from scipy.interpolate import RegularGridInterpolator
    from scipy.sparse.linalg import spsolve

    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", str(tmp_path))
    f, w, a = _points(atlas)
    pts = np.stack([f, np.log(w), a], -1)
    ref = RegularGridInterpolator((atlas.f_hz, np.log(atlas.omega_n), atlas.alpha), atlas.mean[:, 0], method="cubic",
                                  solver=spsolve)(pts)
    first = atlas.predict(f, 3.0, w, a)[0]  # builds and stores
    assert len(list(tmp_path.glob("atlas-spline-*"))) == 3
    second = _fresh(atlas).predict(f, 3.0, w, a)[0]  # read back from disk
    assert np.array_equal(first, ref) and np.array_equal(second, ref)


def test_response_from_cache_equals_computed_and_other_inputs_miss(atlas, tmp_path, monkeypatch):
    from plate_env.identify.forward import Member
    from plate_env.identify.inference import member_response

    w = np.geomspace(atlas.omega_n[0], atlas.omega_n[-1], 40)
    a = np.linspace(atlas.alpha[0], atlas.alpha[-1], 5)
    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", "off")
    assert cache_dir() is None
    plain = member_response(Member(_fresh(atlas), 1.0), 3.0, w, a)[0](17.3)
    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", str(tmp_path))
    built = member_response(Member(_fresh(atlas), 1.0), 3.0, w, a)[0](17.3)
    entries = sorted(tmp_path.glob("response-*"))
    assert len(entries) == 1
    read = member_response(Member(_fresh(atlas), 1.0), 3.0, w, a)[0](17.3)
    for x, y, z in zip(plain, built, read, strict=True):
        assert np.array_equal(x, y) and np.array_equal(x, z)
    # a changed atlas (one value) or another grid: another entry, never the old one
    changed = dataclasses.replace(atlas, mean=atlas.mean + np.where(np.arange(atlas.mean.size).reshape(
        atlas.mean.shape) == 7, 1.0, 0.0))
    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", "off")
    want = member_response(Member(_fresh(changed), 1.0), 3.0, w, a)[0](17.3)
    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", str(tmp_path))
    got = member_response(Member(_fresh(changed), 1.0), 3.0, w, a)[0](17.3)
    assert len(list(tmp_path.glob("response-*"))) == 2
    assert all(np.array_equal(x, y) for x, y in zip(want, got, strict=True))
    assert not np.array_equal(got[0], read[0])
    member_response(Member(_fresh(atlas), 1.0), 3.0, w[:-1], a)
    assert len(list(tmp_path.glob("response-*"))) == 3


def test_unreadable_entry_is_rebuilt(atlas, tmp_path, monkeypatch):
    from plate_env.identify.forward import Member
    from plate_env.identify.inference import member_response

    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", str(tmp_path))
    w = np.geomspace(atlas.omega_n[0], atlas.omega_n[-1], 30)
    a = np.linspace(atlas.alpha[0], atlas.alpha[-1], 4)
    good = member_response(Member(_fresh(atlas), 1.0), 3.0, w, a)[0](21.0)
    (entry,) = tmp_path.glob("response-*")
    for p in entry.glob("*.npy"):
        p.write_bytes(b"not an array")
    again = member_response(Member(_fresh(atlas), 1.0), 3.0, w, a)[0](21.0)
    assert all(np.array_equal(x, y) for x, y in zip(good, again, strict=True))


def test_keys_name_scipys_version_without_importing_scipy():
    import subprocess
    import sys

    import scipy

    code = ("import sys; from plate_env.core.cache import content_key, scipy_version; content_key('k', 1.0); "
            "print(scipy_version(), 'scipy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == [scipy.__version__, "False"]


def test_content_key_depends_on_every_byte():
    x = np.arange(5.0)
    y = x.copy()
    y[3] = np.nextafter(y[3], 10)
    assert content_key("k", x) == content_key("k", x.copy())
    assert content_key("k", x) != content_key("k", y)
    assert content_key("k", x) != content_key("k", x.astype(np.float32))
    assert content_key("k", 3.0) != content_key("k", 12.0)


def test_pybullet_calibration_is_read_back_and_keyed_by_object(tmp_path, monkeypatch):
    pytest.importorskip("pybullet")
    from plate_env.core.objects import ObjectSpec
    from plate_env.physics.pybullet_sheet import calibrate
    from plate_env.physics.pybullet_sheet.scene import SheetConfig

    calls = []

    def fake(obj, config, tol, max_iter):
        calls.append(obj.omega_n)
        return 1.0 + obj.omega_n, obj.omega_n * 1.001

    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(calibrate, "_ringdown_k", fake)
    inner = calibrate._calibrated_k.__wrapped__  # past the per-process cache: the disk's

    def run(obj, config, tol=0.02, max_iter=8):  # calibrated_k's key: the object without its friction angle
        return inner(dataclasses.replace(obj, alpha=calibrate.RINGDOWN_ALPHA), config, tol, max_iter)

    a, b = ObjectSpec(omega_n=40.0, alpha=0.7), ObjectSpec(omega_n=41.0, alpha=0.7)
    first = run(a, SheetConfig())
    assert run(a, SheetConfig()) == first == (41.0, 40.0 * 1.001) and calls == [40.0]
    assert run(b, SheetConfig()) == (42.0, 41.0 * 1.001) and calls == [40.0, 41.0]
    assert run(a, SheetConfig(), tol=0.01) and calls == [40.0, 41.0, 40.0]
    assert run(dataclasses.replace(a, alpha=0.3), SheetConfig()) == first and len(calls) == 3  # alpha: no key


def _store_fails_on_second_file(monkeypatch, exc: BaseException) -> None:
    """``np.save`` inside the cache writes one file, then raises ``exc`` (a full disk, a Ctrl-C)."""
    import plate_env.core.cache as cache

    real, calls = np.save, []

    def save(path, arr, **kw):
        calls.append(path)
        if len(calls) > 1:
            raise exc
        real(path, arr, **kw)

    monkeypatch.setattr(cache.np, "save", save)


@pytest.mark.parametrize("exc", [OSError(28, "No space left on device"), KeyboardInterrupt()])
def test_a_failed_write_leaves_no_temporary_directory(tmp_path, monkeypatch, capsys, exc):
    from plate_env.core.cache import cached_arrays

    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", str(tmp_path))
    _store_fails_on_second_file(monkeypatch, exc)
    arrays = {"a": np.arange(3.0), "b": np.ones(2)}
    if isinstance(exc, OSError):  # computed, not cached, said once on stderr
        got = cached_arrays("unit", "0" * 64, lambda: arrays)
        assert got is arrays and "cannot write the cache" in capsys.readouterr().err
    else:  # an interrupt goes through, and still takes its half-written directory with it
        with pytest.raises(KeyboardInterrupt):
            cached_arrays("unit", "0" * 64, lambda: arrays)
    assert list(tmp_path.iterdir()) == []


def _entries_and_strangers(root):
    """Two entries, a temporary directory left by a crash, and things the cache did not write."""
    from plate_env.core.cache import cached_arrays

    cached_arrays("atlas-spline", "a" * 64, lambda: {"c": np.zeros(1000)})
    cached_arrays("response", "b" * 64, lambda: {"c": np.zeros(3000), "d": np.zeros(10)})
    (root / ".response-x1y2z3w4").mkdir()
    (root / ".response-x1y2z3w4" / "c.npy").write_bytes(b"\0" * 500)
    for stranger in (".ssh", "notes", "response-short"):
        (root / stranger).mkdir()
        (root / stranger / "keep").write_text("not the cache's")
    (root / "README").write_text("not the cache's")


def test_cache_info_and_clear(tmp_path, monkeypatch, capsys):
    from plate_env.cli import main
    from plate_env.core.cache import cache_entries

    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", str(tmp_path))
    _entries_and_strangers(tmp_path)
    entries = cache_entries()
    assert [(e.kind, e.path.name[:14]) for e in entries] == [
        ("temporary", ".response-x1y2"), ("atlas-spline", "atlas-spline-a"), ("response", "response-bbbbb")]
    sizes = {e.kind: e.size_bytes for e in entries}
    assert sizes["temporary"] == 500 and sizes["atlas-spline"] > 8000 and sizes["response"] > 8 * 3010
    assert main(["cache", "info"]) == 0
    out = capsys.readouterr().out
    total = sum(sizes.values())
    assert f"{tmp_path}: 3 entries, {total / 1e6:.1f} MB" in out
    assert "  response: 1 entries" in out and "  atlas-spline: 1 entries" in out and "  temporary: 1 entries" in out
    assert main(["cache", "clear"]) == 0
    assert f"deleted 3 entries, {total / 1e6:.1f} MB" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == [".ssh", "README", "notes", "response-short"]
    assert cache_entries() == []


def test_cache_command_when_off(monkeypatch, capsys):
    from plate_env.cli import main

    monkeypatch.setenv("PLATE_ENV_CACHE_DIR", "off")
    for action in ("info", "clear"):
        assert main(["cache", action]) == 0
        assert "off" in capsys.readouterr().out
