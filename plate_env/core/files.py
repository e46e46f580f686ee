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


# ----------------------------------------------------------------------------------------------- writing
class OutputError(OSError):
    """A file that could not be written (or will not be writable): one line naming it; the file it would have
    replaced is unchanged."""

    def __init__(self, message: str, errno_: int | None = None) -> None:
        super().__init__(message)
        self.errno = errno_

    def __str__(self) -> str:
        return str(self.args[0])


def _named(what: str, path: Path) -> str:
    return f"{what} {str(path)!r}" if what else repr(str(path))


def _probe_dir(directory: Path) -> str | None:
    """Why no file can be created in ``directory`` (None if one can: a file is created there and removed; unlike
    ``os.access``, this sees a read-only file system and holds for root)."""
    import tempfile

    try:
        fd, name = tempfile.mkstemp(prefix=".plate_env-probe-", dir=directory)
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(name)
    return None


def check_output(path: str | Path, what: str = "") -> Path:
    """``path`` as a Path if a file can be written there, checked before any work: not empty, not a directory or
    another special file, its directory exists and a file can be created in it, an existing file is writable.
    ValueError naming ``what`` (e.g. ``"--out"``) and the path otherwise. Nothing is written."""
    text = str(path)
    path = Path(path)
    if not text or path.is_dir():
        raise ValueError(f"{_named(what, path)} is a directory or empty; give a file name")
    kind = special_kind(path)
    if kind is not None:
        raise ValueError(f"{_named(what, path)} is {kind}, not a regular file; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise ValueError(f"{_named(what, path)}: directory {str(parent)!r} does not exist")
    why = _probe_dir(parent)
    if why is not None:
        raise ValueError(f"{_named(what, path)}: directory {str(parent)!r} is not writable ({why})")
    if path.exists() and not os.access(path, os.W_OK):
        raise ValueError(f"{_named(what, path)}: the file exists and is not writable")
    return path


def check_output_dir(path: str | Path, what: str = "") -> Path:
    """``path`` as a Path to a directory files can be written in, created (with its parents) if missing, checked
    before any work; ValueError naming ``what`` and the path otherwise (a file, a device, a read-only place)."""
    text = str(path)
    path = Path(path)
    if not text:
        raise ValueError(f"{_named(what, path)} is empty; give a directory")
    kind = special_kind(path)
    if kind is not None and kind != "a directory":
        raise ValueError(f"{_named(what, path)} is {kind}, not a directory")
    if path.exists() and not path.is_dir():
        raise ValueError(f"{_named(what, path)} is a file, not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{_named(what, path)}: cannot create the directory ({exc.strerror or exc})") from None
    why = _probe_dir(path)
    if why is not None:
        raise ValueError(f"{_named(what, path)}: the directory is not writable ({why})")
    return path


def _new_file_mode(target: Path) -> int:
    """The permission bits the written file gets: the replaced file's, else what ``open(..., "w")`` would give."""
    try:
        return stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mask = os.umask(0o022)
        os.umask(mask)
        return 0o666 & ~mask


def write_atomic(path: str | Path, write, what: str = "") -> Path:
    """Write ``path`` all at once: ``write(tmp)`` writes a temporary file in the same directory (its name ends with
    ``path``'s suffix, which numpy and matplotlib read), which is then flushed to disk and renamed over ``path``
    (``os.replace``). A failure midway (a full disk, an interrupt) leaves ``path`` as it was and no temporary file;
    an OSError is raised again as an :class:`OutputError` naming ``what`` and the file. A symlink is followed (its
    target is replaced); a special file (a device, a FIFO) is refused, never replaced. Returns ``path``."""
    import tempfile

    path = Path(path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    kind = special_kind(target)
    if kind is not None:
        raise OutputError(f"{_named(what, path)} is {kind}, not a regular file; nothing was written")
    existed = target.exists()
    parent = target.parent if str(target.parent) else Path(".")
    tmp = None
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".part{target.suffix}", dir=parent)
        os.close(fd)
        tmp = Path(name)
        write(tmp)
        os.chmod(tmp, _new_file_mode(target))
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)  # a full disk shows here at the latest, before the old file is replaced
        finally:
            os.close(fd)
        os.replace(tmp, target)
        tmp = None
    except OSError as exc:
        kept = f"{str(path)!r} is unchanged" if existed else "no file was written"
        raise OutputError(f"{_named(what, path)}: cannot write: {exc.strerror or exc} ({kept})", exc.errno) from None
    finally:
        if tmp is not None:
            try:
                tmp.unlink()
            except OSError:
                pass
    return path


def write_text_atomic(path: str | Path, text: str, what: str = "", encoding: str = "utf-8") -> Path:
    """:func:`write_atomic` of a text (``encoding``, newlines as given)."""

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding=encoding, newline="") as fh:
            fh.write(text)

    return write_atomic(path, write, what)
