"""The design counts of issue 35 ("Second design step"), for any commit, so that before/after is one command.

    python experiments/design_counts.py [--commits 5860216 HEAD] [--mypy]

Each commit is checked out into a temporary git worktree and read as text and syntax trees (nothing of it is
imported, except by mypy with ``--mypy``). Counts:

- ``method_string_branches``: comparisons of a name or attribute containing ``method`` with a string constant
  (``==``, ``!=``, ``in``, ``not in`` a tuple/list/set of strings) in ``plate_env/`` and ``agents/``;
- ``env_constructor_args``: parameters of ``PlateRotationEnv.__init__`` (``self`` excluded);
- ``experiments_private_imports``: names starting with ``_`` imported from ``plate_env``/``plate_env_agents`` by a
  file under ``experiments/``, imports of a module path with such a component, and private members reached through
  a name such an import bound (``rk._step``);
- ``script_to_script_imports``: imports, in ``experiments/``, of a module that is a file of ``experiments/`` (the
  scripts' shared helper module ``common.py`` and the scripts' own tests ``test_*.py`` are not scripts);
- ``tests_importing_scripts``: the same from ``tests/`` (a name that is also a module of ``tests/`` excluded: it
  imports that module); ``experiments_tests_importing_scripts``: the same from ``experiments/test_*.py``;
- ``import_hooks``: classes defining ``find_spec`` plus statements touching ``sys.meta_path`` in ``plate_env/``;
- ``imports_inside_functions``: import statements inside a function body in ``plate_env/`` and ``agents/``;
- ``modules_over_400_lines`` and the largest, in ``plate_env/`` and ``agents/``;
- ``cli_lines``: lines of the command line (``plate_env/cli.py`` or the largest module of ``plate_env/cli/``);
- ``mypy_errors`` (``--mypy``): errors mypy reports on ``plate_env`` (its default, lenient settings,
  ``--ignore-missing-imports``; a commit's own ``[tool.mypy]`` is not read);
- ``mypy_public_api_errors`` (``--mypy``): errors of ``mypy --strict`` on the public API, the files this checkout's
  ``pyproject.toml`` ``[tool.mypy]`` lists (``plate_env/cli`` read as ``plate_env/cli.py`` where the command line
  was one module), their imports followed silently, as ``tests/test_types.py`` checks them.

Writes ``experiments/results/design_counts.{json,md}``.
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "experiments" / "results"


def _files(root: Path, *dirs: str) -> list[Path]:
    return sorted(p for d in dirs if (root / d).exists() for p in (root / d).rglob("*.py")
                  if ".venv" not in p.parts and "site" not in p.parts)


def _trees(root: Path, *dirs: str) -> dict[Path, ast.Module]:
    out = {}
    for p in _files(root, *dirs):
        try:
            out[p] = ast.parse(p.read_text(encoding="utf-8"), filename=str(p))
        except SyntaxError:
            continue
    return out


def _name_has_method(node: ast.AST) -> bool:
    if isinstance(node, ast.Name):
        return "method" in node.id.lower()
    if isinstance(node, ast.Attribute):
        return "method" in node.attr.lower()
    if isinstance(node, ast.Subscript):
        s = node.slice
        return isinstance(s, ast.Constant) and isinstance(s.value, str) and "method" in s.value
    return False


def _is_str(node: ast.AST) -> bool:
    if isinstance(node, ast.Constant):
        return isinstance(node.value, str)
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return bool(node.elts) and all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts)
    return False


def method_string_branches(trees: dict[Path, ast.Module]) -> int:
    n = 0
    for tree in trees.values():
        for node in ast.walk(tree):
            if isinstance(node, ast.Compare) and len(node.ops) == 1:
                left, right = node.left, node.comparators[0]
                if (_name_has_method(left) and _is_str(right)) or (_name_has_method(right) and _is_str(left)):
                    n += 1
    return n


def env_constructor_args(root: Path) -> int | None:
    for p in _files(root, "plate_env"):
        tree = ast.parse(p.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef) and node.name == "PlateRotationEnv":
                for item in node.body:
                    if isinstance(item, ast.FunctionDef) and item.name == "__init__":
                        a = item.args
                        return len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) - 1
    return None


def _imports(tree: ast.Module) -> list[tuple[str, list[str]]]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.module, [a.name for a in node.names]))
    return out


def experiments_private_imports(trees: dict[Path, ast.Module]) -> int:
    n = 0
    for tree in trees.values():
        bound = set()  # names an import from the package binds (a module or an object)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                bound |= {a.asname or a.name.split(".")[0] for a in node.names
                          if a.name.split(".")[0] in ("plate_env", "plate_env_agents")}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module and node.module.split(".")[0] in (
                    "plate_env", "plate_env_agents"):
                bound |= {a.asname or a.name for a in node.names}
        for module, names in _imports(tree):
            if module.split(".")[0] not in ("plate_env", "plate_env_agents"):
                continue
            if any(part.startswith("_") for part in module.split(".")):
                n += 1
            n += sum(1 for a in names if a.startswith("_"))
        # private members reached through an imported name: rigid_kernels._step, sweeps._from_record
        n += sum(1 for node in ast.walk(tree) if isinstance(node, ast.Attribute) and node.attr.startswith("_")
                 and not node.attr.startswith("__") and isinstance(node.value, ast.Name) and node.value.id in bound)
    return n


def script_imports(trees: dict[Path, ast.Module], scripts: set[str]) -> int:
    return sum(1 for tree in trees.values() for module, _ in _imports(tree) if module.split(".")[0] in scripts)


def import_hooks(trees: dict[Path, ast.Module]) -> int:
    n = 0
    for tree in trees.values():
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef) and any(isinstance(b, ast.FunctionDef) and b.name == "find_spec"
                                                      for b in node.body):
                n += 1
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and isinstance(
                    node.func.value, ast.Attribute) and node.func.value.attr == "meta_path" and node.func.attr in (
                    "append", "insert"):
                n += 1
    return n


def imports_inside_functions(trees: dict[Path, ast.Module]) -> int:
    n = 0
    for tree in trees.values():
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n += sum(1 for node in ast.walk(fn) if isinstance(node, (ast.Import, ast.ImportFrom)))
    # nested functions were counted once per enclosing function: count each statement once instead
    return n if n == 0 else _unique_inner_imports(trees)


def _unique_inner_imports(trees: dict[Path, ast.Module]) -> int:
    seen = set()
    for p, tree in trees.items():
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, (ast.Import, ast.ImportFrom)):
                        seen.add((p, node.lineno, node.col_offset))
    return len(seen)


def long_modules(root: Path, limit: int = 400) -> tuple[int, list[tuple[str, int]]]:
    sizes = [(str(p.relative_to(root)), len(p.read_text(encoding="utf-8").splitlines()))
             for p in _files(root, "plate_env", "agents")]
    big = sorted((s for s in sizes if s[1] > limit), key=lambda s: -s[1])
    return len(big), big[:5]


def cli_lines(root: Path) -> int:
    single = root / "plate_env" / "cli.py"
    if single.exists():
        return len(single.read_text(encoding="utf-8").splitlines())
    return max((len(p.read_text(encoding="utf-8").splitlines()) for p in (root / "plate_env" / "cli").glob("*.py")),
               default=0)


def mypy_errors(root: Path) -> int | None:
    return _mypy_count(root, ["plate_env", "--ignore-missing-imports"])


def public_api_files(root: Path) -> list[str]:
    """This checkout's ``[tool.mypy]`` files as they exist in ``root`` (the CLI package or module)."""
    import tomllib

    files = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["mypy"]["files"]
    return [f if (root / f).exists() or f != "plate_env/cli" else "plate_env/cli.py" for f in files
            if (root / f).exists() or f == "plate_env/cli"]


def mypy_public_api_errors(root: Path) -> int | None:
    return _mypy_count(root, ["--strict", "--follow-imports=silent", "--ignore-missing-imports",
                              *public_api_files(root)])


def _mypy_count(root: Path, args: list[str]) -> int | None:
    done = subprocess.run([sys.executable, "-m", "mypy", "--config-file", "", *args, "--no-error-summary",
                           "--cache-dir", str(Path(tempfile.gettempdir()) / "mypy-counts")],
                          cwd=root, capture_output=True, text=True)
    if "No module named mypy" in done.stderr:
        return None
    return sum(1 for line in done.stdout.splitlines() if re.search(r": error:", line))


def counts(root: Path, with_mypy: bool) -> dict:
    pkg = _trees(root, "plate_env", "agents")
    exp = _trees(root, "experiments")
    tests = _trees(root, "tests")
    # scripts: files of experiments/ but the scripts' one shared helper module (common.py) and their own tests
    scripts = {p.stem for p in (root / "experiments").glob("*.py") if p.stem != "common"
               and not p.stem.startswith("test_")} if (root / "experiments").exists() else set()
    own_tests = {p: t for p, t in exp.items() if p.name.startswith("test_")}
    # a module of tests/ of the same name as a script (tests/cross_cpu.py) is what a test imports by that name
    test_modules = {p.stem for p in (root / "tests").glob("*.py")}
    n_big, biggest = long_modules(root)
    out = {"method_string_branches": method_string_branches(pkg), "env_constructor_args": env_constructor_args(root),
           "experiments_private_imports": experiments_private_imports(exp),
           "script_to_script_imports": script_imports({p: t for p, t in exp.items() if p not in own_tests}, scripts),
           "tests_importing_scripts": script_imports(tests, scripts - test_modules),
           "experiments_tests_importing_scripts": script_imports(own_tests, scripts),
           "import_hooks": import_hooks(_trees(root, "plate_env")),
           "imports_inside_functions": imports_inside_functions(pkg), "modules_over_400_lines": n_big,
           "largest_modules": biggest, "cli_lines": cli_lines(root)}
    if with_mypy:
        out["mypy_errors"] = mypy_errors(root)
        out["mypy_public_api_errors"] = mypy_public_api_errors(root)
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commits", nargs="+", default=["5860216", "HEAD"])
    ap.add_argument("--mypy", action="store_true")
    args = ap.parse_args(argv)
    rows = {}
    for c in args.commits:
        sha = subprocess.run(["git", "rev-parse", "--short", c], cwd=REPO, capture_output=True, text=True,
                             check=True).stdout.strip()
        with tempfile.TemporaryDirectory() as tmp:
            wt = Path(tmp) / "tree"
            subprocess.run(["git", "worktree", "add", "-q", "--detach", str(wt), sha], cwd=REPO, check=True)
            try:
                rows[sha] = counts(wt, args.mypy)
            finally:
                subprocess.run(["git", "worktree", "remove", "--force", str(wt)], cwd=REPO, check=True)
        print(sha, json.dumps(rows[sha]), flush=True)
    keys = [k for k in next(iter(rows.values())) if k != "largest_modules"]
    lines = ["# Design counts (issue 35)", "",
             f"Command: `python experiments/design_counts.py --commits {' '.join(args.commits)}"
             f"{' --mypy' if args.mypy else ''}` (definitions in the script's docstring).", "",
             "| count | " + " | ".join(rows) + " |", "|---|" + "---|" * len(rows)]
    lines += [f"| {k} | " + " | ".join(str(r.get(k)) for r in rows.values()) + " |" for k in keys]
    lines += ["", "Largest modules:", ""]
    lines += [f"- {sha}: " + ", ".join(f"{p} ({n})" for p, n in r["largest_modules"]) for sha, r in rows.items()]
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "design_counts.json").write_text(json.dumps(rows, indent=1) + "\n")
    (RESULTS / "design_counts.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
