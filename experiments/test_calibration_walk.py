"""Issue 40 item 1: a lab's calibration by commands only. The walk of docs/calibration-walk.md runs end to end from
the commands as written on the page (parsed from it, so the page and the test cannot drift): three reference sweeps
from three simulated sources, ``calibrate SWEEP.csv=OMEGA ...``, and the unknown disc read with and without the
calibration. Atlas physics: seconds, not minutes."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from calibration_walk import run_walk, walk_commands

from plate_env.core.units import parse_omega_n

INTERVAL = re.compile(r"95 % interval ([\d.]+)-([\d.]+) rad/s")


@pytest.mark.slow  # 13 s warm; about 60 s with a cold cache of atlas responses at load 20 (2 cores)
def test_the_documented_walk_runs_and_the_calibration_narrows_a_truthful_interval(tmp_path):
    cmds = walk_commands()
    kinds = [c[1] for c in cmds]
    assert kinds.count("sweep") >= 4 and kinds.count("calibrate") == 1 and kinds.count("fit") == 2
    sweeps = [c for c in cmds if c[1] == "sweep"]
    assert len({(c[c.index("--physics") + 1], c[c.index("--model") + 1] if "--model" in c else None)
                for c in sweeps[:3]}) == 3  # three simulated sources
    done = run_walk(cmds, tmp_path)
    for cmd, code, out in done:
        assert code == 0, (cmd, out)
    calibrate = next(c for c in cmds if c[1] == "calibrate")
    refs = [a for a in calibrate[2:] if "=" in a and not a.startswith("-")]
    assert len(refs) == 3  # K = 3, each SWEEP.csv=OMEGA: no references file merged by hand
    unknown = next(c for c in cmds if c[1] == "fit")[2]
    made = next(c for c in sweeps if unknown in c)
    truth = parse_omega_n(made[made.index("--omega-n") + 1])
    assert all(unknown not in r for r in refs)
    calibrated, plain = (out for cmd, _, out in done if cmd[1] == "fit")
    (lo, hi), (ulo, uhi) = ([float(x) for x in INTERVAL.search(o).groups()] for o in (calibrated, plain))
    assert "calibrated by" in calibrated and "uncalibrated" in plain
    assert lo <= truth <= hi
    assert hi / lo < (uhi / ulo) / 10  # the references narrowed the 95 % interval by over 10x in ratio


def test_calibrate_refuses_mismatched_references_by_name(tmp_path, capsys):
    """Each refusal before any calibration work, one line naming the argument."""
    from plate_env.cli import main

    run_walk(walk_commands()[:2], tmp_path)  # disc_a.csv, disc_b.csv
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "disc_a.csv").write_text((tmp_path / "disc_b.csv").read_text())
    (tmp_path / "refs.csv").write_text("object,omega_n_rad_s,f_p_hz,omega_b_deg_s,a_p_deg\ndisc_b,40,12,50,3\n")
    out = str(tmp_path / "c.json")
    for argv, words in [
        (["disc_a.csv=12pi", "./disc_a.csv=20pi"], "is given twice"),
        (["disc_a.csv=12pi", "other/disc_a.csv=20pi"], "'disc_a' is in both"),
        (["disc_a.csv=12pa"], "'disc_a.csv=12pa': omega_n '12pa' is not a number"),
        (["disc_a.csv=40pi"], "outside the identifiable range"),
        (["disc_a.csv"], "give it as disc_a.csv=OMEGA"),
        (["refs.csv=12pi"], "is a references file"),
        (["disc_b.csv=20pi", "refs.csv"], "'disc_b' is in both 'disc_b.csv=20pi' and 'refs.csv'"),
        (["disc_a.csv=12pi", "disc_b.csv=12pi", "missing.csv=3pi"], "no such file"),
    ]:
        full = [str(tmp_path / a) if not a.startswith(("disc", "./", "other", "refs", "missing")) else a
                for a in argv]
        here = os.getcwd()
        os.chdir(tmp_path)
        try:
            code = main(["calibrate", *full, "--amp", "3", "--out", out])
        finally:
            os.chdir(here)
        err = capsys.readouterr().err
        assert code == 2 and words in err and err.count("\n") == 1, (argv, err)
    assert not Path(out).exists()


@pytest.mark.parametrize("name", ["calibration-walk.md"])
def test_the_walk_page_is_in_the_docs_nav(name):
    root = Path(__file__).resolve().parents[1]
    assert name in (root / "mkdocs.yml").read_text() and (root / "docs" / name).is_file()
