"""The README cannot drift from the code or the results.

* every ``python`` block runs (in a fresh process, in a temporary directory); a block preceded by
  ``<!-- readme-test: slow -->`` is marked slow;
* every ``plate-env`` line of a shell block parses with the CLI's own argparse parser (the subcommand and every
  option exist and take the values shown), the scripts and files it names exist, and ``pip`` extras exist;
* shell lines are copy-pasteable: no ``a|b`` alternatives or ``[...]`` placeholders outside quotes;
* the test command is the one ``.ci/run`` runs, verbatim;
* (experiments/test_readme_tables.py: every table between ``<!-- table: NAME -->`` markers, in the README and in
  docs/, equals its rendering from experiments/results/ by experiments/readme_tables.py, and an edited number is
  caught.)
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import shlex
import subprocess
import sys
from importlib.metadata import metadata
from pathlib import Path

import pytest

from plate_env.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()

FENCE = re.compile(r"(?P<mark><!-- readme-test: slow -->\n)?```(?P<lang>\w+)\n(?P<body>.*?)```", re.S)


def blocks(lang: str) -> list[tuple[str, bool]]:
    """(code, slow) of every fenced block of ``lang`` in the README."""
    return [(m["body"], bool(m["mark"])) for m in FENCE.finditer(README) if m["lang"] == lang]


def shell_lines() -> list[str]:
    out = []
    for body, _ in blocks("bash"):
        for line in body.splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                out.append(line)
    return out


def commands(line: str) -> list[list[str]]:
    """The commands of a shell line joined by ``&&``, each split as a shell would, comments dropped."""
    return [shlex.split(part, comments=True) for part in line.split("&&")]


def test_readme_has_blocks_and_stays_short():
    assert len(README.splitlines()) <= 250
    assert len(blocks("python")) >= 3 and len(shell_lines()) >= 8


@pytest.mark.parametrize("index", [pytest.param(i, marks=pytest.mark.slow) if slow else i
                                   for i, (_, slow) in enumerate(blocks("python"))])
def test_python_block_runs(index, tmp_path):
    code, _ = blocks("python")[index]
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, f"README python block {index} failed:\n{code}\n{proc.stderr[-3000:]}"


def _pyproject_extras() -> set[str]:
    return set(metadata("plate-env").get_all("Provides-Extra") or ())


def check_command(argv: list[str]) -> None:
    """Raise AssertionError (or SystemExit from argparse) if ``argv`` names something that does not exist."""
    if argv[0] == "plate-env":
        build_parser().parse_args(argv[1:])  # exits 2 on an unknown subcommand, option or value
        if argv[1] == "fit":
            assert (ROOT / argv[2]).exists(), f"{argv[2]} does not exist"
            if "--forward" in argv:
                from plate_env.surrogate.catalog import forward_model_names

                name = argv[argv.index("--forward") + 1]
                assert name in forward_model_names(), f"--forward {name}: not a shipped forward model"
        for a in argv:
            if re.fullmatch(r"[\w/.-]+\.py:\w+", a):  # a third-party agent file
                assert (ROOT / a.split(":")[0]).exists(), a
    elif argv[0] == "python" and argv[1] != "-m":
        assert (ROOT / argv[1]).exists(), f"{argv[1]} does not exist"
    elif argv[0] == "python" and argv[1] == "-m" and argv[2] in ("rl_zoo3.train", "rl_zoo3.enjoy"):
        env_id = argv[argv.index("--env") + 1]
        assert env_id == "PlateRotation-v0", env_id
        if "--conf-file" in argv:  # a file, or a module whose ``hyperparams`` has the env's entry (rl-zoo3 reads both)
            conf = argv[argv.index("--conf-file") + 1]
            if not (ROOT / conf).exists():
                try:
                    found = importlib.util.find_spec(conf) is not None
                except (ImportError, ValueError):  # a path-like name: its "parent package" does not import
                    found = False
                assert found, f"--conf-file {conf}: no such file or module"
                assert env_id in importlib.import_module(conf).hyperparams, conf
    elif argv[0] == "pip":
        for a in argv:
            m = re.fullmatch(r"\.\[(?P<extras>[\w,]+)\]", a)
            if m:
                unknown = set(m["extras"].split(",")) - _pyproject_extras()
                assert not unknown, f"pip extras {unknown} are not in pyproject.toml"
        assert "-c" in argv and argv[argv.index("-c") + 1] == "constraints.txt", "pip without constraints.txt"
        if "rl_zoo3" in argv:  # rl_zoo3 does not install what its enjoy imports (requests); the rl extra does
            extras = {e for a in argv for m in [re.fullmatch(r"\.\[(?P<extras>[\w,]+)\]", a)] if m
                      for e in m["extras"].split(",")}
            assert "rl" in extras, f"pip installs rl_zoo3 without the rl extra: {shlex.join(argv)}"
    else:
        assert argv[0] in ("ruff", "pytest", "mkdocs"), f"unchecked command {argv[0]!r}"


@pytest.mark.parametrize("line", shell_lines())
def test_shell_line_names_what_exists(line):
    quoted = re.sub(r"\"[^\"]*\"|'[^']*'", "", line.split(" #")[0])
    assert not re.search(r"[|\[\]<>]", quoted), f"not copy-pasteable (a|b or [...] outside quotes): {line}"
    for argv in commands(line):
        check_command(argv)


def test_command_checker_can_fail():
    """The checks above reject what does not exist."""
    with pytest.raises(SystemExit):
        check_command(["plate-env", "fit", "examples/cheese_sweep.csv", "--forwards", "lab"])
    with pytest.raises(SystemExit):
        check_command(["plate-env", "calibrat", "x.csv"])
    with pytest.raises(SystemExit):
        check_command(["plate-env", "identify", "--agent", "nobody"])
    with pytest.raises(AssertionError):
        check_command(["pip", "install", "-c", "constraints.txt", "-e", ".[test,nosuchextra]"])
    with pytest.raises(AssertionError, match="without the rl extra"):
        check_command(["pip", "install", "-c", "constraints.txt", "rl_zoo3"])  # enjoy: no module named 'requests'
    check_command(["pip", "install", "-c", "constraints.txt", "-e", ".[rl]", "rl_zoo3"])
    with pytest.raises(AssertionError):
        check_command(["python", "experiments/no_such_script.py"])
    with pytest.raises(AssertionError):
        check_command(["python", "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "PlateRotation-v0", "--conf-file",
                       "experiments/hyperparams/ppo.yml"])  # the old place of the hyperparameters
    with pytest.raises(AssertionError):
        check_command(["plate-env", "fit", "examples/cheese_sweep.csv", "--amp", "3", "--forward", "tilelink/nobody"])


def test_test_command_is_what_ci_runs():
    test_cmd = next(line for line in shell_lines() if "pytest" in line)
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert test_cmd in ci, f"README test command differs from .ci/run:\n{test_cmd}"


def test_main_command_is_the_identify_job():
    main = shell_lines()[0]
    assert main.startswith("pip install") and "plate-env identify" in main


def test_docs_python_blocks_compile():
    """The docs pages' Python examples are at least valid Python (the README's are run above)."""
    pages = sorted((ROOT / "docs").rglob("*.md"))
    found = 0
    for page in pages:
        for m in FENCE.finditer(page.read_text()):
            if m["lang"] == "python":
                compile(m["body"], f"{page.name} block", "exec")
                found += 1
    assert found >= 2


def _resolves(name: str) -> bool:
    """``a.b.c`` names a module or an attribute of one."""
    import importlib

    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


def test_named_modules_exist_at_their_current_paths():
    """Every ``plate_env.x.y`` the README and the docs name resolves, and not through an old path kept for users
    (docs/layout.md names the old paths on purpose)."""
    import warnings

    pages = [p for p in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))] if p.name != "layout.md"]
    names = sorted({m[1] for p in pages for m in re.finditer(r"`(plate_env(?:_agents)?(?:\.\w+)+)", p.read_text())})
    assert len(names) > 10
    bad = []
    for name in names:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ok = _resolves(name)
        moved = [str(w.message) for w in caught if "moved to" in str(w.message)]
        if not ok or moved:
            bad.append(f"{name}: {moved[0] if moved else 'does not exist'}")
    assert not bad, bad
    assert not _resolves("plate_env.no_such_module") and not _resolves("plate_env.env.NoSuchThing")


def test_rl_extra_gives_a_working_zoo():
    """rl-zoo3's train and enjoy run from the install lines alone (issue 41 item 3; a fresh venv,
    experiments/results/zoo_fresh_venv.md): the ``rl`` extra lists what rl_zoo3 imports but does not install
    (``requests``, for enjoy) and what ``plate_env_agents.zoo`` needs (PyYAML), and every line of the README and
    the docs that installs rl_zoo3 installs the extra with it."""
    import tomllib

    rl = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["rl"]
    names = {re.match(r"[A-Za-z0-9_.-]+", req)[0].lower().replace("_", "-") for req in rl}
    assert {"requests", "pyyaml", "stable-baselines3"} <= names, rl
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    lines = [line.strip() for page in pages for line in page.read_text().splitlines()
             if line.strip().startswith("pip install") and "rl_zoo3" in line]
    assert len(lines) >= 2, lines  # the README's and docs/training.md's
    for line in lines:
        for argv in commands(line):
            if argv[0] == "pip":
                check_command(argv)
