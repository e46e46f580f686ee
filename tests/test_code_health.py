"""Design rules checked on the source text (ast, no imports): dependencies one way down the layers, one home per
fact, short functions, no process-wide settings changed by the library.

``python tests/test_code_health.py`` prints the report these tests check (import cycles, imports that go up a layer,
the longest functions).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "plate_env"
#: No function or method in the project may be longer than this many lines (decorators and docstring included),
#: numba kernels (``@numba.njit``: one compiled loop, split only at a cost in speed) aside.
MAX_FUNCTION_LINES = 120
#: The only package of the library whose modules may import the shipped agents (the folder ``agents/``, installed
#: as ``plate_env_agents``): the command line, one module per command, is the application layer (``plate-env
#: identify`` and ``bench`` run agents, ``build policy`` trains one); everything else in plate_env, the benchmark
#: included, is the core below it and sees agents only through the protocol (plate_env.protocol).
AGENTS_SEAM = "plate_env.cli"
AGENTS_PACKAGE = "plate_env_agents"

#: The layers, lowest first: a module may import modules of its own layer and of the layers below, never above.
#: A module belongs to the layer of the longest prefix that names it. This is the one place the order is written
#: (experiments/layer_crossings.py reads it).
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("core", ("plate_env.core",)),
    ("surrogate", ("plate_env.surrogate",)),
    ("physics", ("plate_env.physics",)),
    ("identify", ("plate_env.identify",)),
    ("run", ("plate_env.run",)),
    ("env", ("plate_env.env",)),
    ("agents", (AGENTS_PACKAGE,)),
    ("bench", ("plate_env.bench",)),
    ("build", ("plate_env.build",)),
    ("edge", ("plate_env", "plate_env.cli", "plate_env.plotting", "plate_env.__main__")),
)


def layer_of(module: str) -> int | None:
    """The index in :data:`LAYERS` of ``module``'s layer (longest matching prefix), None outside the project."""
    best, rank = -1, None
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best:
                best, rank = len(p), i
    return rank


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    if parts[0] == "agents":  # the folder agents/ installs as plate_env_agents
        parts[0] = AGENTS_PACKAGE
    return ".".join(parts)


def _sources(*folders: str) -> dict[str, tuple[Path, ast.Module]]:
    out = {}
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*.py")):
            out[_module_name(path)] = (path, ast.parse(path.read_text(), filename=str(path)))
    return out


def _imports(name: str, path: Path, tree: ast.Module, modules: set[str] = frozenset()) -> list[str]:
    """Every module this one imports, at module level or inside functions (lazy imports count too).

    ``from pkg import x`` names ``pkg.x`` where that is one of ``modules``, else ``pkg``."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            found += [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
    return found


def import_graph(*folders: str) -> dict[str, set[str]]:
    """Module -> the modules of the project it imports (plate_env by default; ``"agents"`` adds the shipped
    agents). Explicit imports only: the parent packages' ``__init__`` that Python runs on the way to a submodule
    are not edges."""
    src = _sources(*(folders or (PACKAGE,)))
    return {name: {m for m in _imports(name, path, tree, set(src)) if m in src and m != name}
            for name, (path, tree) in src.items()}


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Every import from a module to one of a higher layer, as "importer -> imported (layer -> layer)"."""
    out = []
    for name, deps in sorted(graph.items()):
        for dep in sorted(deps):
            lo, hi = layer_of(name), layer_of(dep)
            if lo is not None and hi is not None and hi > lo:
                out.append(f"{name} -> {dep} ({LAYERS[lo][0]} -> {LAYERS[hi][0]})")
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def is_numba_kernel(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Whether a function is compiled by numba (a decorator ``numba.njit``/``numba.jit``, called or not)."""
    names = {ast.unparse(d.func if isinstance(d, ast.Call) else d) for d in node.decorator_list}
    return bool(names & {"numba.njit", "numba.jit", "njit", "jit"})


def function_lengths(kernels: bool = False) -> list[tuple[int, str]]:
    """(lines, "path:line name") of every function and method in the project, longest first; numba kernels only
    with ``kernels``."""
    out = []
    for _, (path, tree) in _sources(PACKAGE, "agents", "experiments", "tests").items():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and (kernels or not is_numba_kernel(node)):
                first = min([node.lineno] + [d.lineno for d in node.decorator_list])
                out.append((node.end_lineno - first + 1, f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"))
    return sorted(out, reverse=True)


def test_no_import_cycle_in_the_library():
    graph = import_graph()
    assert len(graph) > 30  # the walk found the package
    assert cycles(graph) == []


def test_cycle_finder_finds_a_planted_cycle():
    graph = import_graph()
    graph["plate_env.identify.estimate"] = graph["plate_env.identify.estimate"] | {"plate_env.identify.api"}
    assert any({"plate_env.identify.estimate", "plate_env.identify.api"} <= set(c) for c in cycles(graph))


def test_every_module_has_a_layer():
    graph = import_graph(PACKAGE, "agents")
    assert {layer_of(m) for m in graph} == set(range(len(LAYERS)))  # every layer holds a module
    assert [m for m in graph if layer_of(m) is None] == []
    assert layer_of("plate_env.identify.api") == 3 and layer_of("plate_env.cli") == len(LAYERS) - 1
    assert layer_of("plate_env") == len(LAYERS) - 1 and layer_of("numpy") is None


def test_imports_go_one_way_down_the_layers():
    graph = import_graph(PACKAGE, "agents")
    assert sum(len(d) for d in graph.values()) > 100  # the walk found the imports, the agents' too
    assert cycles(graph) == []
    assert upward_imports(graph) == []


def test_the_layer_check_finds_a_planted_upward_import():
    graph = import_graph(PACKAGE, "agents")
    graph["plate_env.core.objects"] = graph["plate_env.core.objects"] | {"plate_env.physics.nuisance"}
    graph["plate_env.env.rotation"] = graph["plate_env.env.rotation"] | {"plate_env_agents.bayes"}
    assert upward_imports(graph) == ["plate_env.core.objects -> plate_env.physics.nuisance (core -> physics)",
                                     "plate_env.env.rotation -> plate_env_agents.bayes (env -> agents)"]


def test_the_core_does_not_import_the_agents():
    importers = {name for name, (path, tree) in _sources(PACKAGE).items()
                 if any(m.split(".")[0] in (AGENTS_PACKAGE, "agents") for m in _imports(name, path, tree))}
    assert importers and all(m.startswith(AGENTS_SEAM + ".") for m in importers), importers
    # the walk sees the seam's own (lazy) imports: identify and bench run agents, build trains a policy
    assert {"plate_env.cli.identify", "plate_env.cli.bench", "plate_env.cli.build"} <= importers


def test_parameter_indices_are_imported_from_params_only():
    params = ROOT / PACKAGE / "physics" / "tilelink" / "params.py"
    names = {t.id for node in ast.parse(params.read_text()).body if isinstance(node, ast.Assign)
             for target in node.targets for t in (target.elts if isinstance(target, ast.Tuple) else [target])
             if isinstance(t, ast.Name) and t.id.startswith("P_")}
    assert {"P_MASS", "P_RECEVERY", "P_V0"} <= names
    wrong = []
    for name, (_, tree) in _sources(PACKAGE, "agents", "experiments", "tests").items():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module != "plate_env.physics.tilelink.params":
                wrong += [f"{name}: {a.name} from {node.module}" for a in node.names if a.name in names]
            if isinstance(node, ast.Attribute) and node.attr in names and not (
                    isinstance(node.value, ast.Name) and node.value.id == "params"):
                wrong.append(f"{name}:{node.lineno}: .{node.attr}")
    assert wrong == []


def test_the_library_does_not_choose_a_matplotlib_backend():
    calls = [f"{name}:{node.lineno}" for name, (_, tree) in _sources(PACKAGE).items() for node in ast.walk(tree)
             if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "use"
             and isinstance(node.func.value, ast.Name) and node.func.value.id == "matplotlib"]
    assert calls == []


def test_no_function_longer_than_the_limit():
    lengths = function_lengths()
    assert lengths[0][0] > 50  # the walk measured real functions
    assert [f for f in lengths if f[0] > MAX_FUNCTION_LINES] == []
    kernels = sorted(set(function_lengths(kernels=True)) - set(lengths), reverse=True)
    # numba kernels live in the kernel modules (kernels.py, rigid_kernels.py, kernels_v2.py) or in experiments
    assert len(kernels) >= 10 and all(re.search(r"(^|/|_)kernels(_v\d+)?\.py:", k) or k.startswith("experiments/")
                                      for _, k in kernels)
    assert kernels[0][1].endswith("pointmass_probe")  # the exemption is the numba kernels, the longest among them


if __name__ == "__main__":
    print("import cycles in plate_env:", cycles(import_graph()) or "none")
    print("imports up a layer:", upward_imports(import_graph(PACKAGE, "agents")) or "none")
    print(f"longest functions (limit {MAX_FUNCTION_LINES} lines):")
    for n, where in function_lengths()[:8]:
        print(f"  {n:4d}  {where}")
