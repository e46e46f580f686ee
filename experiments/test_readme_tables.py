"""The generated tables of the README and the docs pages (experiments/readme_tables.py): each equals its result
file in experiments/results, an edited number is caught, every table renders. A test of the experiments' own code,
beside it (pytest collects experiments/ too), so that the package's tests in tests/ import no script."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import readme_tables

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_tables_match_their_result_files():
    pages = readme_tables.pages()
    assert ROOT / "README.md" in pages
    stale = {str(p.relative_to(ROOT)): readme_tables.stale(p.read_text()) for p in pages}
    stale = {k: v for k, v in stale.items() if v}
    assert not stale, f"tables differ from experiments/results (run python experiments/readme_tables.py): {stale}"


def test_readme_shows_generated_tables():
    names = [m["name"] for m in readme_tables.MARKER.finditer(README)]
    assert {"forward_models_choice", "forward_models_within", "leaderboard_tilelink-v0"} <= set(names)
    unknown = [m["name"] for p in readme_tables.pages() for m in readme_tables.MARKER.finditer(p.read_text())
               if m["name"] not in readme_tables.TABLES]
    assert not unknown


def test_an_edited_number_is_caught():
    """Change one digit inside each marked table of the README and of every docs page: the check names that table
    and no other."""
    checked = set()
    for page in readme_tables.pages():
        page_text = page.read_text()
        for m in readme_tables.MARKER.finditer(page_text):
            body = m["body"]
            digit = re.search(r"\d\.\d", body) or re.search(r"(?<=\| )\d", body)  # a decimal, else a count cell
            assert digit, (page.name, m["name"])
            i = digit.start()
            edited = body[:i] + str((int(body[i]) + 1) % 10) + body[i + 1:]
            text = page_text[:m.start("body")] + edited + page_text[m.end("body"):]
            assert readme_tables.stale(text) == [m["name"]], (page.name, m["name"])
            checked.add(m["name"])
    assert {"leaderboard_tilelink-v0", "leaderboard_atlas-v0", "rigid_fast_routes", "bench_models"} <= checked


def test_generator_renders_every_table():
    for name in readme_tables.TABLES:
        assert "|---|" in readme_tables.render(name), name
    with pytest.raises(KeyError):
        readme_tables.render("no_such_table")


