"""MkDocs hooks for the API reference (mkdocs.yml ``hooks:``; not a page of the site).

* ``<!-- api-modules: plate_env.core -->`` in a page becomes the package's own docstring and one mkdocstrings block
  (``::: plate_env.core.x``) per public module of that package (subpackages get their own marker), found on disk
  at build time, so a module added to a layer is documented without editing the page.
* The docstrings' Sphinx roles (``:mod:`~plate_env.core.objects```, ``:func:`identify```, ...) are rendered as code
  linked to the object's entry when the API reference has one (mkdocs-autorefs), instead of showing the role.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: Packages whose import name differs from their folder (pyproject's package-dir).
FOLDERS = {"plate_env_agents": ROOT / "agents"}
API = re.compile(r"<!-- api-modules: (?P<pkg>[\w.]+) -->")
ROLE = re.compile(r":(?:py:)?(?:mod|func|class|meth|attr|data|exc|obj):<code>(?P<tilde>~)?(?P<target>[\w.]+)</code>")


def _folder(package: str) -> Path:
    top, _, rest = package.partition(".")
    base = FOLDERS.get(top, ROOT / top)
    return base.joinpath(*rest.split(".")) if rest else base


def modules(package: str) -> list[str]:
    """The public modules of ``package`` (files not starting with ``_``), sorted."""
    folder = _folder(package)
    if not folder.is_dir():
        raise FileNotFoundError(f"api-modules: no package folder {folder} for {package!r}")
    return [f"{package}.{p.stem}" for p in sorted(folder.glob("*.py")) if not p.stem.startswith("_")]


def _blocks(package: str) -> str:
    head = f"::: {package}\n    options:\n      members: false\n" if (_folder(package) / "__init__.py").exists() else ""
    return head + "".join(f"\n::: {name}\n" for name in modules(package))


def on_page_markdown(markdown: str, **kwargs) -> str:
    return API.sub(lambda m: _blocks(m["pkg"]), markdown)


def on_page_content(html: str, **kwargs) -> str:
    def link(m: re.Match) -> str:
        target = m["target"]
        shown = target.rsplit(".", 1)[-1] if m["tilde"] else target
        if "." not in target:  # a bare name: no identifier to resolve
            return f"<code>{shown}</code>"
        return f'<autoref identifier="{target}" optional><code>{shown}</code></autoref>'

    return ROLE.sub(link, html)
