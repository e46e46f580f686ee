"""What every artifact written by ``plate-env build`` records about how it was made: the command, the package's
version and the git commit of the source it was built from (None when the package is not a git checkout)."""

from __future__ import annotations

import shlex
import subprocess
from collections.abc import Sequence
from pathlib import Path

from plate_env.identify.lab_calibration_file import package_version


def git_commit(where: str | Path | None = None) -> str | None:
    """The commit of the git checkout holding ``where`` (default: this package's source), ``+dirty`` appended when
    tracked files differ from it; None for an installed wheel, or without git."""
    where = Path(where) if where is not None else Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "-C", str(where), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(where), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{head}+dirty" if dirty else head or None


def build_record(argv: Sequence[str]) -> dict:
    """``{"command": "plate-env build ...", "plate_env": version, "commit": ...}`` for the arguments ``argv`` given
    after ``plate-env build``."""
    return {"command": shlex.join(["plate-env", "build", *argv]), "plate_env": package_version(),
            "commit": git_commit()}


__all__: Sequence[str] = ("build_record", "git_commit")
