"""Reading the files a user names (a lab CSV, a calibration, a suite, a model, a hyperparameter file): one gate
for every reader.

A path that is not a regular file is refused before it is read: a device (``/dev/zero`` reads forever, until the
memory is gone), a FIFO (the read blocks until some writer comes), a directory, a socket. Text is decoded with the
file named in the error, and JSON nested past :data:`MAX_JSON_DEPTH` is refused (Python's parser would raise a
RecursionError). Every refusal is a ``ValueError`` naming the file and what it should be.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

#: Deepest nesting of arrays and objects a JSON input may have (every file this project reads nests fewer than 10
#: levels; Python's parser recurses once a level and fails near 1000).
MAX_JSON_DEPTH = 100

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def special_kind(path: str | Path) -> str | None:
    """What ``path`` is when it exists and is not a regular file (``"a directory"``, ``"a FIFO (named pipe)"``,
    ...), else None (a regular file, a symlink to one, or nothing there)."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def check_regular(path: str | Path, what: str, missing_ok: bool = False) -> Path:
    """``path`` as a Path if it is a regular file (or, with ``missing_ok``, nothing yet), else ValueError naming
    ``what`` (e.g. ``"--calibration"``), the path and what it is. Nothing is opened."""
    path = Path(path)
    kind = special_kind(path)
    if kind is not None:
        raise ValueError(f"{what} {str(path)!r} is {kind}, not a regular file; give the path of a file")
    if not missing_ok and not path.is_file():
        raise ValueError(f"{what} {str(path)!r}: no such file")
    return path


def read_text(path: str | Path, what: str, encoding: str = "utf-8") -> str:
    """The text of a regular file (:func:`check_regular`); ValueError naming the file when it cannot be read or is
    not ``encoding`` text."""
    path = check_regular(path, what)
    try:
        return path.read_text(encoding=encoding)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what} {str(path)!r} is not UTF-8 text (byte {exc.start}: {exc.reason}); save it as "
                         "UTF-8") from None
    except OSError as exc:
        raise ValueError(f"{what} {str(path)!r}: cannot read: {exc.strerror or exc}") from None


def _depth(doc) -> int:
    """The nesting depth of a parsed JSON document (iterative: a deep document does not recurse here)."""
    deepest, stack = 0, [(doc, 1)]
    while stack:
        node, level = stack.pop()
        if isinstance(node, (dict, list)):
            deepest = max(deepest, level)
            stack.extend((v, level + 1) for v in (node.values() if isinstance(node, dict) else node))
    return deepest


def parse_json(text: str, where: str, strict: bool = False):
    """``text`` as JSON, refused past :data:`MAX_JSON_DEPTH` levels of nesting; ``strict``: ``NaN`` and
    ``Infinity`` refused too (RFC 8259). ValueError naming ``where``."""

    def refuse(name: str):
        raise ValueError(f"{where}: {name} is not a JSON number (strict JSON: write a finite number)")

    too_deep = f"{where}: JSON nested deeper than {MAX_JSON_DEPTH} levels; not a file this reads"
    try:
        doc = json.loads(text, parse_constant=refuse if strict else None)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where}: not valid JSON ({exc})") from None
    except RecursionError:
        raise ValueError(too_deep) from None
    if _depth(doc) > MAX_JSON_DEPTH:
        raise ValueError(too_deep)
    return doc


def read_json(path: str | Path, what: str, strict: bool = False):
    """The JSON document of a regular file (:func:`read_text`, :func:`parse_json`)."""
    return parse_json(read_text(path, what), f"{what} {str(path)!r}", strict)
