"""The type check of the public API (issue 35): mypy, strict, on the files pyproject.toml's ``[tool.mypy]`` lists,
run here so that the README's one test command runs it too. ``mypy`` in the checkout runs the same check.

A cold run (no ``.mypy_cache``) reads the listed files and, silently, everything they import: ~40 s on 2 loaded cores
here, a few seconds with the cache."""

from __future__ import annotations

import re
from pathlib import Path

from mypy import api

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: mypy installs tomli
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "pyproject.toml"


def _mypy(*args: str) -> tuple[str, int]:
    out, err, status = api.run(["--config-file", str(CONFIG), *args])
    return out + err, status


def test_the_public_api_has_no_type_errors(monkeypatch):
    monkeypatch.chdir(ROOT)  # the config's files are relative to the checkout
    listed = tomllib.loads(CONFIG.read_text())["tool"]["mypy"]["files"]
    assert "plate_env/cli" in listed and "plate_env/__init__.py" in listed
    assert all((ROOT / f).exists() for f in listed), listed
    report, status = _mypy()
    errors = [line for line in report.splitlines() if ": error:" in line]
    print(report)
    assert status == 0 and errors == [], "\n".join(errors)
    checked = re.search(r"no issues found in (\d+) source files", report)
    assert checked and int(checked[1]) >= len(listed), report  # the listed files were read (cli/ is a package)


def test_the_check_is_strict(tmp_path, monkeypatch):
    """What the configured check refuses: a function without annotations, a bare ``dict`` (the settings the public
    API is held to, not mypy's lenient default)."""
    monkeypatch.chdir(ROOT)
    bad = tmp_path / "untyped.py"
    bad.write_text("def f(x):\n    return x\n\n\ndef g() -> dict:\n    return {}\n")
    report, status = _mypy(str(bad))
    assert status == 1
    assert "[no-untyped-def]" in report and "[type-arg]" in report, report
