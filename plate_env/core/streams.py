"""Standard output is for results: what code below Python prints on file descriptor 1 is sent elsewhere.

``print`` and ``sys.stdout`` are Python's; C extensions (PyBullet's ``loadSoftBody`` mesh counts), numba, a plug-in
agent's ``os.write(1, ...)`` and child processes (Ray's raylet and workers, pool workers) write to file descriptor
1 directly. :func:`fd_redirected` points that descriptor elsewhere during a block (``os.dup2``);
:func:`stdout_to_stderr` does it for Python and the descriptor together, so that ``plate-env ... --json`` prints one
JSON document on stdout whatever the libraries and agents it runs print.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator

__all__ = ["fd_redirected", "stdout_to_stderr"]


def _flush_c_stdio() -> None:
    """Flush C's stdio buffers (``fflush(NULL)``), where C code's ``printf`` waits while fd 1 is a pipe or file."""
    with contextlib.suppress(OSError, AttributeError, TypeError):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def fd_redirected(fd: int, target_fd: int) -> Iterator[bool]:
    """Point file descriptor ``fd`` at ``target_fd``'s file during the block; yields whether it did.

    Python's ``sys.stdout``/``sys.stderr`` and C's stdio buffers are flushed before (what was written before the
    block goes where it was meant to) and C's again before ``fd`` is restored (what C code wrote during the block
    goes to the target). Child processes started during the block inherit the redirected descriptor. Output of other
    threads during the block is redirected too. When ``fd`` is not open (a closed stdout) nothing is redirected."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    _flush_c_stdio()
    try:
        saved = os.dup(fd)
    except OSError:
        saved = None
    if saved is not None:
        try:
            os.dup2(target_fd, fd)
        except OSError:  # the target is not open: leave fd as it is
            os.close(saved)
            saved = None
    try:
        yield saved is not None
    finally:
        if saved is not None:
            _flush_c_stdio()
            os.dup2(saved, fd)
            os.close(saved)


@contextlib.contextmanager
def stdout_to_stderr() -> Iterator[None]:
    """What the block prints on stdout goes to stderr: Python's ``sys.stdout`` (``print``, Ray's driver threads,
    which print worker deaths to ``sys.stdout``) and file descriptor 1 (C code, agents, child processes started in
    the block). For the work of a command whose results are printed after it."""
    with fd_redirected(1, 2), contextlib.redirect_stdout(sys.stderr):  # fd first: it flushes the real stdout
        try:
            yield
        finally:
            with contextlib.suppress(Exception):
                sys.stderr.flush()
