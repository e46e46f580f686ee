"""What every artifact written by ``plate-env build`` records about how it was made: the command, the package's
version and the git commit of the source it was built from (None when the package is not a git checkout)."""

from __future__ import annotations

import os
import platform
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


def machine() -> dict:
    """What decides the last bits of a simulated number besides the code: the CPU numba compiles for
    (``NUMBA_CPU_NAME`` when set, else the host's, as LLVM names it), the BLAS kernels OpenBLAS picked (its core
    type; ``OPENBLAS_CORETYPE`` overrides it) and the library versions. A rebuild on another CPU can differ at
    nodes that amplify last-bit differences (``experiments/results/atlas_rebuild.md``); setting these two variables
    to the recorded values (and an empty ``NUMBA_CACHE_DIR``) reproduced a shipped atlas bit for bit there."""
    import numba
    import numpy as np
    import threadpoolctl
    from llvmlite import binding as ll

    ll.initialize_native_target()
    blas = sorted(f"{i.get('internal_api')} {i.get('version')} {i.get('architecture')}"
            for i in threadpoolctl.threadpool_info() if i.get("user_api") == "blas")
    return {"numba_cpu": os.environ.get("NUMBA_CPU_NAME") or ll.get_host_cpu_name(), "blas": blas,
            "machine": platform.machine(), "numpy": np.__version__, "numba": numba.__version__}


__all__: Sequence[str] = ("build_record", "git_commit", "machine")
