"""What names a benchmark record: the suite's content, the agent (class, options, source, model file) and the code
that decides an episode's outcome, found by following the imports of the env, the episode loop and the backend
(:func:`outcome_modules`), so that no list of file names has to be kept by hand."""

from __future__ import annotations

import ast
import functools
import hashlib
import inspect
import json
from pathlib import Path

from plate_env.bench.suites import Suite

#: Version of the episode record (part of every record's key).
RECORD_FORMAT = 1


def _sha_file(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def source_fingerprint(path: str | Path) -> str:
    """SHA-256 of a Python file's code: its syntax tree without docstrings (comments and docstrings do not
    change what it does, so editing them keeps records valid)."""
    tree = ast.parse(Path(path).read_text())
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return hashlib.sha256(ast.dump(tree).encode()).hexdigest()


def _modules(root: Path) -> dict[str, Path]:
    """plate_env's modules under ``root`` (the package folder): dotted name -> file."""
    out = {}
    for p in sorted(root.rglob("*.py")):
        parts = list(p.relative_to(root.parent).with_suffix("").parts)
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    return out


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of ``modules`` that ``name`` imports (at module level or in a function), with the parent packages
    Python runs on the way to them."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        for t in targets:
            while t:
                if t in modules:
                    found.add(t)
                t = t.rpartition(".")[0]
    return found


#: Where an episode's outcome is decided: the env and its episode loop; with the backend's module (its entry in
#: :data:`plate_env.physics.PHYSICS`) the roots of :func:`outcome_modules`.
OUTCOME_ROOTS = ("plate_env.env.rotation", "plate_env.env.episode")


def outcome_modules(physics: str) -> list[str]:
    """The modules that decide an episode's outcome on ``physics``: everything the env, the episode loop and the
    backend import, directly or through others (lazy imports in functions included), read from the source (ast).
    Other backends, the benchmark, the executors, the command line and plots are not reached, so editing them keeps
    records valid."""
    from plate_env.physics import PHYSICS

    modules = _modules(Path(__file__).resolve().parents[1])
    todo = [*OUTCOME_ROOTS, PHYSICS.entries[PHYSICS.check(physics)].partition(":")[0]]
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        todo += sorted(_imports(name, modules[name], modules) - seen)
    return sorted(seen)


@functools.lru_cache(maxsize=8)
def code_fingerprint(physics: str) -> str:
    """SHA-256 over the code that decides an episode's outcome on ``physics`` (:func:`outcome_modules`, docstrings
    left out) and the data files (atlases, calibrations, forward models; not their manifest, which lists them).
    Computed once per process and physics."""
    root = Path(__file__).resolve().parents[1]
    modules = _modules(root)
    files = [modules[m] for m in outcome_modules(physics)]
    data = sorted(p for ext in ("json", "npz") for p in (root / "data").glob(f"*.{ext}")
                  if p.name != "MANIFEST.json")  # the list of the files, not an input of any outcome
    h = hashlib.sha256()
    for p in files + data:
        h.update(str(p.relative_to(root)).encode())
        h.update((source_fingerprint(p) if p.suffix == ".py" else _sha_file(p)).encode())
    return h.hexdigest()


def agent_fingerprint(agent) -> dict:
    """What names an agent in a record: its class, its public options of plain types, the SHA-256 of its source
    file and, where the agent has one, its own ``fingerprint()`` (e.g. a policy's model file)."""
    cls = type(agent)
    options = {k: repr(v) for k, v in sorted(vars(agent).items()) if not k.startswith("_") and k not in
               ("context", "rng") and isinstance(v, (int, float, str, bool, tuple, type(None), Path))}
    try:
        source = source_fingerprint(inspect.getsourcefile(cls))
    except (TypeError, OSError, SyntaxError):
        source = None
    extra = agent.fingerprint() if callable(getattr(agent, "fingerprint", None)) else None
    return {"class": f"{cls.__module__}.{cls.__qualname__}", "options": options, "source": source, "extra": extra}


def run_key(suite: Suite, agent_fp: dict, max_budget_s: float) -> str:
    text = json.dumps({"format": RECORD_FORMAT, "suite": suite.sha256, "code": code_fingerprint(suite.physics),
                       "agent": agent_fp, "budget": max_budget_s}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:24]
