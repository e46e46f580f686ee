"""A registry of one kind of thing by name (physics backends, agents, identification methods): the one list of
names, each loaded lazily from its ``"module:attribute"`` entry point (so naming a backend imports none)."""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Registry:
    """Names of one ``kind`` and their entry points, ``{"name": "package.module:Attribute"}``, in a stated order."""

    kind: str
    entries: Mapping[str, str] = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        """The registered names, in their order."""
        return tuple(self.entries)

    def check(self, name: object) -> str:
        """``name`` if registered, else ValueError naming the kind, the value and the choices."""
        if not isinstance(name, str) or name not in self.entries:
            raise ValueError(f"unknown {self.kind} {name!r}; choose one of {self.names}")
        return name

    def load(self, name: object) -> Any:
        """The object ``name`` stands for (its module imported now)."""
        module, _, attribute = self.entries[self.check(name)].partition(":")
        return getattr(importlib.import_module(module), attribute)


__all__ = ["Registry"]
