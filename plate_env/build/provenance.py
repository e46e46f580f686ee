"""What every artifact written by ``plate-env build`` records about how it was made: the command, the package's
version and the git commit of the source it was built from (None when the package is not a git checkout).

Every shipped file (``plate_env/data`` and ``plate_env_agents/models``) is listed in ``plate_env/data/MANIFEST.json``
(:data:`MANIFEST`): per file its SHA-256, the command that made it, the package version, the commit (``"unknown"``
where the file was made without recording it) and the SHA-256 of its inputs. ``plate-env build`` updates the
manifest's entry when it writes a shipped file (:func:`record_in_manifest`); :func:`check_manifest` lists what
disagrees (``tests/test_manifest.py``)."""

from __future__ import annotations

import hashlib
import importlib.util
import json
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


#: The manifest of the shipped files, in ``plate_env/data``. It is not an input of any outcome: benchmark record keys
#: (``plate_env.bench.fingerprint.code_fingerprint``) leave it out, so rewriting it keeps records valid.
MANIFEST = "MANIFEST.json"
#: The fields of a manifest entry.
ENTRY_FIELDS = ("sha256", "command", "plate_env", "commit", "inputs")
#: The packages whose files the manifest lists, and their shipped folders (paths in the manifest start with them).
SHIPPED = {"plate_env": ("data",), "plate_env_agents": ("models",)}


def file_sha256(path: str | Path) -> str:
    """The SHA-256 (hex) of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def package_root(package: str) -> Path:
    """The folder of an installed package of :data:`SHIPPED` (found without importing it)."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise ValueError(f"package {package!r} is not installed")
    return Path(list(spec.submodule_search_locations)[0])


def manifest_path() -> Path:
    return package_root("plate_env") / "data" / MANIFEST


def inputs_dir() -> Path:
    """Where the builders' frozen inputs are shipped: ``plate_env/data/inputs`` (measured numbers and sweeps that
    ``plate-env build`` reads by default and never recomputes; each listed in the manifest with the command that
    measured it)."""
    return package_root("plate_env") / "data" / "inputs"


def shipped_files() -> dict[str, Path]:
    """Every shipped file but the manifest: manifest name (``plate_env/data/...``) -> path. Python sources and
    build records beside a file (``*.provenance.json``) are not shipped data."""
    out = {}
    for package, folders in SHIPPED.items():
        root = package_root(package)
        for folder in folders:
            for p in sorted((root / folder).rglob("*")):
                if p.is_file() and p.name != MANIFEST and p.suffix != ".py" and "__pycache__" not in p.parts \
                        and not p.name.endswith(".provenance.json"):
                    out[f"{package}/{p.relative_to(root).as_posix()}"] = p
    return out


def manifest_name(path: str | Path) -> str | None:
    """The manifest name of ``path`` when it is a shipped file's place, else None."""
    path = Path(path).resolve()
    for package, folders in SHIPPED.items():
        root = package_root(package).resolve()
        for folder in folders:
            if path.is_relative_to(root / folder):
                return f"{package}/{path.relative_to(root).as_posix()}"
    return None


def load_manifest(path: str | Path | None = None) -> dict:
    """The manifest (``{"files": {name: entry}}``); an empty one when the file does not exist."""
    path = Path(path) if path is not None else manifest_path()
    return json.loads(path.read_text()) if path.exists() else {"files": {}}


def write_manifest(manifest: dict, path: str | Path | None = None) -> None:
    path = Path(path) if path is not None else manifest_path()
    files = dict(sorted(manifest["files"].items()))
    path.write_text(json.dumps({**manifest, "files": files}, indent=1, sort_keys=False) + "\n")


def record_in_manifest(out: str | Path, record: dict, inputs: dict[str, str | Path] | None = None) -> bool:
    """Put a freshly built file ``out`` into the manifest with its build ``record`` (:func:`build_record`) and its
    ``inputs`` (name -> path, hashed here); False (nothing written) when ``out`` is not a shipped file's place."""
    name = manifest_name(out)
    if name is None:
        return False
    entry = {"sha256": file_sha256(out), "command": record["command"], "plate_env": record["plate_env"],
             "commit": record["commit"] or "unknown",
             "inputs": {k: {"path": manifest_name(v) or str(v), "sha256": file_sha256(v)}
                        for k, v in (inputs or {}).items()}}
    manifest = load_manifest()
    manifest["files"][name] = entry
    write_manifest(manifest)
    return True


def command_problem(command: str, subcommands: Sequence[str], root: Path | None = None) -> str | None:
    """Why ``command`` names no way to make a file (None when it does): ``plate-env build ARTIFACT ...`` with an
    artifact of ``subcommands``, ``python SCRIPT ...`` with a script that exists under ``root`` (a checkout;
    None: scripts are not checked), or ``by hand: WHAT`` (a specification written, not computed: an atlas grid)."""
    if command.startswith("by hand: ") and len(command) > len("by hand: "):
        return None
    words = shlex.split(command)
    if words[:2] == ["plate-env", "build"]:
        return None if len(words) > 2 and words[2] in subcommands else f"no build artifact {words[2:3]}"
    if words[:1] == ["python"] and len(words) > 1:
        if root is None or (root / words[1]).is_file():
            return None
        return f"no script {words[1]}"
    return "neither plate-env build nor python SCRIPT"


def check_manifest(manifest: dict, files: dict[str, Path], subcommands: Sequence[str],
                   root: Path | None = None) -> list[str]:
    """What disagrees between ``manifest`` and the shipped ``files`` (:func:`shipped_files`): a file not listed, a
    listed file missing, a SHA-256 that differs, a missing field, a command naming no build artifact or script
    (:func:`command_problem`), an input whose recorded SHA-256 differs from the input shipped under that name."""
    entries = manifest.get("files", {})
    out = [f"{n}: not in the manifest" for n in sorted(set(files) - set(entries))]
    out += [f"{n}: listed, not shipped" for n in sorted(set(entries) - set(files))]
    for name in sorted(set(files) & set(entries)):
        e = entries[name]
        missing = [f for f in ENTRY_FIELDS if not e.get(f) and f != "inputs"] + (["inputs"] if "inputs" not in e
                                                                                 else [])
        if missing:
            out.append(f"{name}: no {', '.join(missing)}")
            continue
        if e["sha256"] != file_sha256(files[name]):
            out.append(f"{name}: sha256 {e['sha256'][:12]} listed, the file's is {file_sha256(files[name])[:12]}")
        why = command_problem(e["command"], subcommands, root)
        if why:
            out.append(f"{name}: command {e['command']!r}: {why}")
        for key, inp in e["inputs"].items():
            shipped = files.get(inp.get("path", ""))
            if shipped is not None and inp.get("sha256") != file_sha256(shipped):
                out.append(f"{name}: input {key} ({inp['path']}) differs from the hash recorded")
    return out


__all__: Sequence[str] = ("ENTRY_FIELDS", "MANIFEST", "SHIPPED", "build_record", "check_manifest", "command_problem",
                          "file_sha256", "git_commit", "inputs_dir", "load_manifest", "machine", "manifest_name",
                          "manifest_path", "package_root", "record_in_manifest", "shipped_files", "write_manifest")
