"""One registry per kind (plate_env.core.registry): physics backends, agents, identification methods and forward
models are listed once, and every place that offers a choice reads that list."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from plate_env.cli import build_parser
from plate_env.core.registry import Registry
from plate_env.identify.api import METHODS
from plate_env.physics import PHYSICS
from plate_env.surrogate.catalog import forward_model_names
from plate_env_agents import AGENTS

ROOT = Path(__file__).resolve().parents[1]


def _choices(command: str, option: str) -> tuple:
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    action = next(a for a in sub.choices[command]._actions if option in a.option_strings)
    return tuple(action.choices)


def test_every_entry_loads_what_its_name_says():
    for name in PHYSICS.names:
        cls = PHYSICS.load(name)
        assert callable(getattr(cls, "run", None)), name
    for name in AGENTS.names:
        assert AGENTS.load(name).name == name


def test_the_command_line_offers_the_registered_names():
    assert _choices("probe", "--physics") == _choices("identify", "--physics") == PHYSICS.names
    assert _choices("identify", "--agent") == AGENTS.names
    assert _choices("fit", "--method") == METHODS
    assert "lab" in forward_model_names()


def test_an_unknown_name_is_refused_naming_the_choices():
    reg = Registry("widget", {"a": "math:sqrt"})
    assert reg.load("a")(4.0) == 2.0
    for bad in ("b", None, 3):
        with pytest.raises(ValueError, match=r"unknown widget .*; choose one of \('a',\)"):
            reg.load(bad)


def test_no_name_list_is_copied_by_hand():
    """No tuple or list literal in the library or the agents holds two or more names of one registry (outside the
    registries themselves): a choice offered anywhere reads the registry."""
    kinds = {"physics": set(PHYSICS.names), "agents": set(AGENTS.names), "methods": set(METHODS)}
    found = []
    for folder in ("plate_env", "agents"):
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.Tuple, ast.List)):
                    words = {e.value for e in node.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)}
                    found += [f"{path.relative_to(ROOT)}:{node.lineno} {kind}" for kind, names in kinds.items()
                              if len(words & names) >= 2 and not (kind == "methods" and "METHODS" in
                                                                  path.read_text().splitlines()[node.lineno - 1])]
    assert found == []
