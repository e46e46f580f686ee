"""A disk cache of arrays derived from shipped data (spline coefficients of atlases and forward-model responses).

Entries are keyed by the SHA-256 of everything they are computed from: :data:`CACHE_VERSION` (raised when the code
that computes an entry changes), the numpy and scipy versions, and the inputs' own bytes (the atlas arrays, the
grid): an entry is found only for exactly the inputs it was made from, so a stale one is never used. Each entry is
a directory of ``.npy`` files and a manifest (each array's name, dtype, shape and whether its values were all
finite), written under a temporary name and renamed into place (a crash leaves no half entry); an entry that is
unreadable or disagrees with its manifest (a file deleted, replaced by another shape, a NaN written into it) is
rebuilt. Large entries are memory-mapped read-only (a probe reads the slices it needs).

A cache that cannot be written (a read-only home, a full disk) is said once per process, and what was computed is
kept in memory for the rest of the process (computed once per process, not once per use).

Where: ``$PLATE_ENV_CACHE_DIR``, else ``$XDG_CACHE_HOME/plate_env``, else ``~/.cache/plate_env``;
``PLATE_ENV_CACHE_DIR=off`` disables it (everything is computed in memory, as before). Deleting the directory is
always safe.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Raise when the computation of a cached entry changes (old entries are then never found again).
CACHE_VERSION = 1
#: An entry's directory name: its kind and the SHA-256 of its inputs (:func:`content_key`).
ENTRY_NAME = re.compile(r"([a-z][a-z0-9-]*)-([0-9a-f]{64})")
#: A temporary directory's name (an entry being written): ``.<kind>-`` and ``tempfile.mkdtemp``'s 8 characters.
TEMP_NAME = re.compile(r"\.([a-z][a-z0-9-]*)-([a-z0-9_]{8})")
#: The file of an entry that lists its arrays (:func:`_manifest`); an entry without it is rebuilt.
MANIFEST = "manifest.json"

#: Entries computed in this process that could not be stored (a read-only or full disk): ``(root, kind, key)`` ->
#: arrays. Kept for the process's life, so one is computed once per process even when it cannot be persisted.
_UNSTORED: dict[tuple[str, str, str], dict[str, np.ndarray]] = {}
#: The cache directories this process already said it cannot write (said once per process).
_WARNED: set[str] = set()


def cache_dir() -> Path | None:
    """The cache directory, or None when caching is off (``PLATE_ENV_CACHE_DIR=off``)."""
    env = os.environ.get("PLATE_ENV_CACHE_DIR")
    if env is not None:
        return None if env.strip().lower() in ("", "off", "0", "none") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "plate_env"


@functools.lru_cache(maxsize=1)
def scipy_version() -> str:
    """scipy's version, read from its installed metadata's folder name (``scipy-1.17.1.dist-info`` beside the
    package) without importing scipy (0.05-0.1 s: a fit reading the cache needs none of it), else from scipy."""
    spec = importlib.util.find_spec("scipy")
    if spec is not None and spec.submodule_search_locations:
        found = list(Path(next(iter(spec.submodule_search_locations))).parent.glob("scipy-*.dist-info"))
        if len(found) == 1:
            return found[0].name[len("scipy-"):-len(".dist-info")]
    import scipy

    return scipy.__version__


def content_key(*parts) -> str:
    """SHA-256 (hex) of the cache version, the numpy/scipy versions and ``parts`` (arrays by dtype, shape and bytes;
    anything else by its ``repr``)."""
    h = hashlib.sha256(f"plate_env-cache-v{CACHE_VERSION} numpy {np.__version__} scipy {scipy_version()}".encode())
    for p in parts:
        if isinstance(p, np.ndarray):
            a = np.ascontiguousarray(p)
            h.update(f"array {a.dtype.str} {a.shape}".encode())
            h.update(a.tobytes())
        else:
            h.update(f"value {p!r}".encode())
        h.update(b"|")
    return h.hexdigest()


def _manifest(arrays: dict[str, np.ndarray]) -> dict[str, dict]:
    """Each array's dtype, shape and, for numbers, whether every value is finite (what a read-back entry must
    match)."""
    out = {}
    for name, arr in arrays.items():
        a = np.asarray(arr)
        out[name] = {"dtype": a.dtype.str, "shape": list(a.shape),
                     "finite": bool(np.isfinite(a).all()) if a.dtype.kind in "fc" else None}
    return out


def entry_problem(entry: Path, arrays: dict[str, np.ndarray]) -> str | None:
    """Why the arrays read from ``entry`` are not what was stored there (None if they are): its manifest missing or
    unreadable, an array missing or added, another dtype or shape, a non-finite value where all were finite."""
    try:
        want = json.loads((entry / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return f"no readable {MANIFEST} ({exc})"
    if not isinstance(want, dict) or sorted(want) != sorted(arrays):
        return f"arrays {sorted(arrays)}, manifest {sorted(want) if isinstance(want, dict) else want!r}"
    for name, arr in arrays.items():
        spec = want[name]
        if not isinstance(spec, dict) or spec.get("dtype") != arr.dtype.str or spec.get("shape") != list(arr.shape):
            return f"{name}.npy is {arr.dtype.str} {list(arr.shape)}, manifest {spec!r}"
        if spec.get("finite") and not np.isfinite(arr).all():
            return f"{name}.npy has non-finite values"
    return None


def _read_entry(entry: Path, mmap: bool) -> dict[str, np.ndarray] | None:
    """The arrays of ``entry`` if they are readable and match its manifest, else None (the entry is deleted, when
    it can be, to be rebuilt)."""
    try:
        arrays = {p.stem: np.load(p, mmap_mode="r" if mmap else None, allow_pickle=False)
                  for p in sorted(entry.glob("*.npy"))}
        if entry_problem(entry, arrays) is None:
            return arrays
    except (OSError, ValueError):  # unreadable: rebuilt
        pass
    shutil.rmtree(entry, ignore_errors=True)
    return None


def cached_arrays(kind: str, key: str, build: Callable[[], dict[str, np.ndarray]], mmap: bool = False,
                  note: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of entry ``kind``/``key``: read from the cache, or ``build()`` them, store them and return them.
    ``mmap``: read large arrays memory-mapped (read-only). ``note``: printed to stderr before a build (a slow one:
    the user sees what the wait is for). An entry that fails validation (:func:`entry_problem`) is rebuilt; one
    that cannot be stored is kept in memory for the rest of the process."""
    root = cache_dir()
    if root is None:
        return build()
    memo = (str(root), kind, key)
    if memo in _UNSTORED:
        return _UNSTORED[memo]
    entry = root / f"{kind}-{key}"
    if entry.is_dir():
        arrays = _read_entry(entry, mmap)
        if arrays is not None:
            return arrays
    if note:
        print(f"plate-env: {note} (once; cached in {root})", file=sys.stderr, flush=True)
    arrays = build()
    tmp = None
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{kind}-", dir=root))
        for name, arr in arrays.items():
            np.save(tmp / f"{name}.npy", np.asarray(arr), allow_pickle=False)
        (tmp / MANIFEST).write_text(json.dumps(_manifest(arrays)), encoding="utf-8")
        try:
            tmp.rename(entry)
            tmp = None
        except OSError:  # another process stored it first: theirs is the same
            pass
    except OSError as exc:  # a read-only or full disk: computed, not cached (kept in memory for this process)
        _UNSTORED[memo] = arrays
        if str(root) not in _WARNED:
            _WARNED.add(str(root))
            print(f"plate-env: cannot write the cache {root}: {exc} (computed in memory; said once)",
                  file=sys.stderr, flush=True)
    finally:  # a failed or interrupted write leaves no temporary directory behind
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return arrays


@dataclass(frozen=True)
class CacheEntry:
    """One directory of the cache: its kind (``atlas-spline``, ``response``, ``pybullet-k``; ``temporary`` for a
    write that never finished), its path and its size in bytes."""

    kind: str
    path: Path
    size_bytes: int


def _dir_size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink())


def cache_entries(root: Path | None = None) -> list[CacheEntry]:
    """The entries in the cache directory (``root``, default :func:`cache_dir`), sorted by path: only directories
    this module writes (:data:`ENTRY_NAME`, and :data:`TEMP_NAME` of a write that never finished), nothing else
    the directory may hold. Empty when the directory does not exist or caching is off."""
    root = cache_dir() if root is None else root
    if root is None or not root.is_dir():
        return []
    out = []
    for p in sorted(root.iterdir()):
        if not p.is_dir() or p.is_symlink():
            continue
        m = ENTRY_NAME.fullmatch(p.name)
        if m:
            out.append(CacheEntry(m[1], p, _dir_size(p)))
        elif TEMP_NAME.fullmatch(p.name):
            out.append(CacheEntry("temporary", p, _dir_size(p)))
    return out


def clear_cache(root: Path | None = None) -> list[CacheEntry]:
    """Delete every entry of :func:`cache_entries` (and nothing else in the directory); returns what was deleted.
    Safe at any time: an entry is only ever computed again."""
    entries = cache_entries(root)
    for e in entries:
        shutil.rmtree(e.path, ignore_errors=True)
    return entries
