"""Whether the tile-link kernels can keep their numba compilation on disk (``CACHE``), decided once at import.

numba's ``cache=True`` needs a writable place: ``NUMBA_CACHE_DIR``, else the ``__pycache__`` beside the source,
else the user's cache directory (``~/.cache/numba``). With none (a read-only install and a read-only home) numba
refuses to define the function ("cannot cache function ... no locator available") and every tile-link command
failed; here the kernels then compile in memory (each process compiles them again, ~10-30 s) with one warning
naming the fix. A ``NUMBA_CACHE_DIR`` that is not a writable directory is named as numba's setting.
"""

from __future__ import annotations

import os
import tempfile
import warnings
from pathlib import Path


def _writable_dir(path: Path) -> bool:
    """``path`` is a directory this process can write a file into (or can be created as one)."""
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            return False
        probe = probe.parent
    if not (probe.is_dir() and os.access(probe, os.W_OK | os.X_OK)):
        return False
    if probe != path:
        return True
    try:
        with tempfile.NamedTemporaryFile(dir=path):
            return True
    except OSError:  # read-only file system, full disk, quota
        return False


def can_cache(source: Path = Path(__file__)) -> tuple[bool, str | None]:
    """``(usable, warning)``: whether numba's disk cache works for kernels defined in ``source``, and the warning
    to give when it does not."""
    env = os.environ.get("NUMBA_CACHE_DIR")
    if env:
        if _writable_dir(Path(env)):
            return True, None
        return False, (f"NUMBA_CACHE_DIR={env!r} (numba's compilation cache) is not a writable directory or is full: "
                       "the tile-link kernels compile in memory, again in every process; point NUMBA_CACHE_DIR at "
                       "a writable directory with free space")
    from numba.misc.appdirs import AppDirs

    user = Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)
    if _writable_dir(source.parent / "__pycache__") or _writable_dir(user):
        return True, None
    return False, (f"no writable place for numba's compilation cache (beside {str(source.parent)!r} or in "
                   f"{str(user)!r}): the tile-link kernels compile in memory, again in every process; set "
                   "NUMBA_CACHE_DIR to a writable directory to keep them")


CACHE, _why = can_cache()
if _why:
    warnings.warn(_why, stacklevel=2)
