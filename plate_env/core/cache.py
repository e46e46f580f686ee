"""A disk cache of arrays derived from shipped data (spline coefficients of atlases and forward-model responses).

Entries are keyed by the SHA-256 of everything they are computed from: :data:`CACHE_VERSION` (raised when the code
that computes an entry changes), the numpy and scipy versions, and the inputs' own bytes (the atlas arrays, the
grid): an entry is found only for exactly the inputs it was made from, so a stale one is never used. Each entry is
a directory of ``.npy`` files written under a temporary name and renamed into place (a crash leaves no half entry);
an unreadable entry is rebuilt. Large entries are memory-mapped read-only (a probe reads the slices it needs).

Where: ``$PLATE_ENV_CACHE_DIR``, else ``$XDG_CACHE_HOME/plate_env``, else ``~/.cache/plate_env``;
``PLATE_ENV_CACHE_DIR=off`` disables it (everything is computed in memory, as before). Deleting the directory is
always safe.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
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


def cached_arrays(kind: str, key: str, build: Callable[[], dict[str, np.ndarray]], mmap: bool = False,
                  note: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of entry ``kind``/``key``: read from the cache, or ``build()`` them, store them and return them.
    ``mmap``: read large arrays memory-mapped (read-only). ``note``: printed to stderr before a build (a slow one:
    the user sees what the wait is for)."""
    root = cache_dir()
    if root is None:
        return build()
    entry = root / f"{kind}-{key}"
    if entry.is_dir():
        try:
            return {p.stem: np.load(p, mmap_mode="r" if mmap else None, allow_pickle=False)
                    for p in sorted(entry.glob("*.npy"))}
        except (OSError, ValueError):  # unreadable: rebuilt below
            shutil.rmtree(entry, ignore_errors=True)
    if note:
        print(f"plate-env: {note} (once; cached in {root})", file=sys.stderr, flush=True)
    arrays = build()
    tmp = None
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{kind}-", dir=root))
        for name, arr in arrays.items():
            np.save(tmp / f"{name}.npy", np.asarray(arr), allow_pickle=False)
        try:
            tmp.rename(entry)
            tmp = None
        except OSError:  # another process stored it first: theirs is the same
            pass
    except OSError as exc:  # a read-only or full disk: computed, not cached
        print(f"plate-env: cannot write the cache {root}: {exc}", file=sys.stderr, flush=True)
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
