"""Run the calibration walk of docs/calibration-walk.md, its commands exactly as written there, and record the output.

    python experiments/calibration_walk.py [--workdir DIR]

Writes experiments/results/calibration_walk.md: each command, its exit code and output, the machine's load and the
wall time. ``experiments/test_calibration_walk.py`` runs the same commands (:func:`walk_commands`) and checks the
answer.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import shlex
import subprocess
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "calibration-walk.md"
RESULTS = ROOT / "experiments" / "results" / "calibration_walk.md"


def walk_commands(doc: Path = DOC) -> list[list[str]]:
    """Every ``plate-env`` command of the page's ``bash`` blocks, in order, split as a shell would."""
    out, inside = [], False
    for line in doc.read_text().splitlines():
        if line.startswith("```"):
            inside = line.strip() == "```bash"
            continue
        if inside and line.strip().startswith("plate-env "):
            out.append(shlex.split(line, comments=True))
    return out


def run_walk(commands: list[list[str]], workdir: Path) -> list[tuple[list[str], int, str]]:
    """Run each command in ``workdir`` through the CLI's ``main`` (in this process): (command, exit code, stdout)."""
    from plate_env.cli import main

    done = []
    here = Path.cwd()
    os.chdir(workdir)
    try:
        for cmd in commands:
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf):
                code = main(cmd[1:])
            done.append((cmd, code, buf.getvalue()))
    finally:
        os.chdir(here)
    return done


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", type=Path, default=None, help="where the CSVs and cal.json go (default: a temp dir)")
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        done = run_walk(walk_commands(), work)
    wall = time.perf_counter() - t0
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT).stdout
    lines = ["# The calibration walk, run", "",
             f"`python experiments/calibration_walk.py` at commit `{commit.strip()}`: the commands of "
             f"docs/calibration-walk.md as written, {wall:.1f} s wall in all (load {load0:.1f} at the start, "
             f"{os.getloadavg()[0]:.1f} at the end; 2 cores, shared).", ""]
    for cmd, code, out in done:
        lines += [f"`{shlex.join(cmd)}` (exit {code})", "", "```", out.rstrip(), "```", ""]
    RESULTS.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
