"""Issue 37 (hardening, round three), items 5, 6, 11, 12 and 13: special files, malformed suites and JSON, messages
that name the problem, nothing ignored or clamped silently, hand-edited calibrations. One test per item; each failed
at the commit before its fix (see the closing note of the issue).

The special-file cases run in a child process under a 4 GB address-space limit and a per-case alarm: before the fix
``/dev/zero`` was read until memory ran out and a FIFO blocked forever, and neither may take the test run with it.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from plate_env.cli import main
from plate_env.identify import lab_calibration_file as lcf

SUITES = Path(__file__).resolve().parents[1] / "plate_env" / "data" / "suites"


def _run(argv: list[str], capsys) -> tuple[int, str]:
    capsys.readouterr()
    code = main(argv)
    return code, capsys.readouterr().err


def _refused(argv: list[str], capsys, *needles: str) -> str:
    """``argv`` exits 2 with one line on stderr holding every needle."""
    code, err = _run(argv, capsys)
    assert code == 2, (argv, code, err)
    assert err.count("\n") == 1 and all(n in err for n in needles), (argv, err)
    return err


def _suite(tmp_path: Path, tag: str, edit) -> str:
    """A copy of atlas-v0 (one object) under a new name, changed by ``edit``; its path."""
    d = json.loads((SUITES / "atlas-v0.json").read_text())
    d["objects"] = d["objects"][:1]
    d["name"] = f"bad{tag}-v0"
    edit(d)
    path = tmp_path / f"bad{tag}-v0.json"
    path.write_text(json.dumps(d))
    return str(path)


def _refs(path: Path, discs: dict[str, float], rows_each: int = 16) -> Path:
    """A references CSV: each disc's 3 deg sweep drawn from the rigid_limit atlas's mean (omega_n rad/s)."""
    from plate_env.surrogate.atlas import load_atlas_file

    atlas = load_atlas_file("atlas_tilelink_rigid_limit_f2.npz")
    f = np.linspace(10.0, 40.0, rows_each)
    lines = ["object,omega_n_rad_s,f_p_hz,omega_b_deg_s,stderr_deg_s,unstable"]
    for name, w in discs.items():
        mean, _, _ = atlas.predict(f, 3.0, w, math.radians(45.0))
        lines += [f"{name},{w!r},{float(x)!r},{float(y)!r},5,0" for x, y in zip(f, mean, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _edited_paper_calibration(tmp_path: Path, edit) -> str:
    """The shipped paper calibration, edited by ``edit`` and its content hash recomputed (as a hand edit would)."""
    from importlib import resources

    d = json.loads((resources.files("plate_env") / "data" / lcf.PAPER_FILE).read_text())
    edit(d)
    body = {k: v for k, v in d.items() if k != "content_sha256"}
    d["content_sha256"] = lcf.content_hash(body)
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(d))
    return str(path)


# ------------------------------------------------------------------------------------------------------ item 5
#: The child process: each case is an argv for plate-env (or "env" for PlateRotationEnv(calibration=...)), run under
#: an address-space limit and an alarm; prints one JSON line per case: the exit code (or "hang", "MemoryError")
#: and stderr.
DRIVER = r"""
import contextlib, io, json, resource, signal, sys
resource.setrlimit(resource.RLIMIT_AS, (4 << 30, resource.getrlimit(resource.RLIMIT_AS)[1]))
from plate_env.cli import main

def alarm(*_):
    raise TimeoutError
signal.signal(signal.SIGALRM, alarm)
for argv in json.loads(sys.argv[1]):
    err = io.StringIO()
    signal.alarm(20)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            if argv[0] == "env":
                from plate_env.env import PlateRotationEnv
                try:
                    PlateRotationEnv(physics="atlas", amplitudes_deg=(3.0,), calibration=argv[1])
                    code = 0
                except ValueError as exc:
                    print(exc, file=sys.stderr)
                    code = 2
            else:
                code = main(argv)
    except TimeoutError:
        code = "hang"
    except MemoryError:
        code = "MemoryError"
    finally:
        signal.alarm(0)
    print(json.dumps({"argv": argv, "code": code, "err": err.getvalue()}), flush=True)
"""


def test_item5_special_files_are_refused_before_any_read(tmp_path):
    """``/dev/zero``, a FIFO and a directory as every file a user names: the fit CSV, ``--calibration``,
    ``calibrate``'s references, an ``sb3:`` zip, ``--suite``, ``build --within``, ``build policy --hyperparams`` and
    the env's ``calibration=``: each refused at once, exit 2, one line naming the path and what it is (5860216:
    MemoryError, exit 3, after eating the memory; a FIFO hung)."""
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    folder = tmp_path / "folder.json"
    folder.mkdir()
    (tmp_path / "disc.csv").write_text("f_p_hz,omega_b_deg_s\n20,300\n")
    out = str(tmp_path / "out.json")
    cases = []
    for special in ("/dev/zero", str(fifo), str(folder)):
        cases += [["fit", special, "--amp", "3"],
                  ["fit", str(tmp_path / "disc.csv"), "--amp", "3", "--calibration", special],
                  ["calibrate", special, "--amp", "3", "--out", out],
                  ["bench", "--suite", special if special.endswith(".json") else str(tmp_path / "zero.json"),
                   "--agent", "grid", "--no-cache"],
                  ["bench", "--suite", "atlas-v0", "--agent", f"sb3:{special}", "--limit", "1", "--no-cache"],
                  ["build", "design-discrepancy", "--within", special, "--out", out],
                  ["build", "policy", "--out", str(tmp_path / "p.zip"), "--hyperparams", special, "--timesteps", "8"],
                  ["env", special]]
    os.symlink("/dev/zero", tmp_path / "zero.json")
    proc = subprocess.run([sys.executable, "-c", DRIVER, json.dumps(cases)], capture_output=True, text=True,
                          timeout=600, cwd=tmp_path)
    results = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert len(results) == len(cases), proc.stderr[-2000:]
    for r in results:
        lines = [x for x in r["err"].splitlines() if "warning" not in x]
        assert r["code"] == 2, r
        assert len(lines) == 1 and "not a regular file" in lines[0], r


# ------------------------------------------------------------------------------------------------------ item 6
def test_item6_malformed_suites_deep_json_and_huge_cells_are_input_errors(tmp_path, capsys):
    """Suite values of the wrong kind, JSON nested 100,000 deep and a CSV cell of 1 MB: exit 2 naming the file and
    the value (5860216: TypeError, numpy's seed error, RecursionError, csv's field-size error, all exit 3)."""
    def obj(key, value):
        return lambda d: d["objects"][0].__setitem__(key, value)

    bad = {"cost_model": (lambda d: d.__setitem__("cost_model", [1, 2]), "cost_model"),
           "objects": (lambda d: d.__setitem__("objects", 5), "objects"),
           "seed": (obj("seed", -1), "seed = -1"),
           "kwarg": (lambda d: d["env_kwargs"].__setitem__("colour", "red"), "['colour']"),
           "mass": (obj("mass_g", None), "mass_g = None"),
           "options": (lambda d: d["env_kwargs"].__setitem__("physics_options", [1]), "physics_options")}
    for tag, (edit, needle) in bad.items():
        path = _suite(tmp_path, tag, edit)
        _refused(["bench", "--suite", path, "--agent", "grid", "--limit", "1", "--no-cache", "--no-progress"], capsys,
                 needle, Path(path).name)
    deep = "[" * 100_000 + "]" * 100_000
    (tmp_path / "deep-v0.json").write_text(deep)
    _refused(["bench", "--suite", str(tmp_path / "deep-v0.json"), "--agent", "grid", "--no-cache"], capsys,
             "deep-v0.json", "nested deeper than")
    (tmp_path / "deep.json").write_text(deep)
    (tmp_path / "disc.csv").write_text("f_p_hz,omega_b_deg_s\n20,300\n")
    _refused(["fit", str(tmp_path / "disc.csv"), "--amp", "3", "--calibration", str(tmp_path / "deep.json")], capsys,
             "deep.json", "nested deeper than")
    (tmp_path / "cell.csv").write_text("f_p_hz,omega_b_deg_s\n" + "1" * 1_000_000 + ",2\n")
    _refused(["fit", str(tmp_path / "cell.csv"), "--amp", "3"], capsys, "cell.csv", "131072")
    (tmp_path / "cellref.csv").write_text("object,omega_n_rad_s,f_p_hz,omega_b_deg_s\na,31.4," + "1" * 1_000_000
                                          + ",2\n")
    _refused(["calibrate", str(tmp_path / "cellref.csv"), "--amp", "3", "--out", str(tmp_path / "c.json")], capsys,
             "cellref.csv", "131072")


# ----------------------------------------------------------------------------------------------------- item 11
def test_item11_messages_name_the_value_and_the_file(tmp_path, capsys, monkeypatch):
    """Each message names what is wrong (5860216: "could not convert string to float", "Out of range float values
    are not JSON compliant", "'<' not supported between instances of 'str' and 'int'", "'b' has another
    omega_n_rad_s", a UTF-8 error without the file, "[Errno 21]", "a bug" for a pickled policy.pth, and calibrate
    --out a directory refused after the calibration)."""
    bench = ["--agent", "grid", "--limit", "1", "--no-cache", "--no-progress"]
    path = _suite(tmp_path, "str", lambda d: d["objects"][0].__setitem__("mass_g", "heavy"))
    _refused(["bench", "--suite", path, *bench], capsys, "objects[0]", "mass_g = 'heavy' is not a number")
    path = _suite(tmp_path, "nan", lambda d: d["objects"][0].__setitem__("alpha_deg", float("nan")))
    _refused(["bench", "--suite", path, *bench], capsys, "badnan-v0.json", "NaN is not a JSON number")
    _refused(["bench", "--suite", "atlas-v0", "--agent", "grid:n='5'", "--limit", "1", "--no-cache"], capsys,
             "n = '5' is not an integer", "[1, 500]")
    refs = tmp_path / "refs.csv"
    refs.write_text("object,omega_n_rad_s,f_p_hz,omega_b_deg_s\na,31.4,20,400\nb,nan,20,380\nb,nan,22,390\n")
    _refused(["calibrate", str(refs), "--amp", "3", "--out", str(tmp_path / "c.json")], capsys,
             "line 3", "omega_n_rad_s = 'nan'", "finite")
    (tmp_path / "latin1.json").write_bytes("{\"schema\": \"caf\xe9\"}".encode("latin-1"))
    (tmp_path / "disc.csv").write_text("f_p_hz,omega_b_deg_s\n20,300\n")
    _refused(["fit", str(tmp_path / "disc.csv"), "--amp", "3", "--calibration", str(tmp_path / "latin1.json")],
             capsys, "latin1.json", "not UTF-8")
    err = _refused(["fit", str(tmp_path), "--amp", "3"], capsys, str(tmp_path), "is a directory")
    assert "Errno" not in err
    # calibrate --out a directory: refused before the references are even read
    monkeypatch.setattr(lcf, "read_reference_csv", lambda *a, **k: pytest.fail("the references were read"))
    _refused(["calibrate", str(refs), "--amp", "3", "--out", str(tmp_path)], capsys, "--out", "is a directory")
    monkeypatch.undo()
    # a model zip whose policy.pth is a pickle of something besides tensors: refused by name, not "a bug"
    pytest.importorskip("stable_baselines3")
    import pickle
    import zipfile
    from importlib import resources

    shipped = resources.files("plate_env_agents") / "models" / "ppo_plate.zip"
    evil = tmp_path / "pickled.zip"
    with zipfile.ZipFile(str(shipped)) as z, zipfile.ZipFile(evil, "w") as out:
        for name in z.namelist():
            out.writestr(name, pickle.dumps({"x": print}) if name == "policy.pth" else z.read(name))
    code, err = _run(["bench", "--suite", "atlas-v0", "--agent", f"sb3:{evil}", "--limit", "1", "--no-cache"], capsys)
    lines = [x for x in err.splitlines() if "warning" not in x]
    assert code == 2 and len(lines) == 1 and "pickled.zip" in lines[0] and "pickled objects" in lines[0], err


# ----------------------------------------------------------------------------------------------------- item 12
def test_item12_nothing_given_is_ignored_clamped_or_counted_twice(tmp_path, capsys):
    """An a_p_deg column against --amp, a suite seed of 1.7, --forward '', --executor '', probe --measure 0, 1e4
    reference rows, one disc under 5 names: each refused naming the value and what is allowed (5860216: the column
    won, seed 1, the defaults, 2 periods "stable", a calibration of 10,000 rows, K = 5)."""
    (tmp_path / "a12.csv").write_text("f_p_hz,omega_b_deg_s,a_p_deg\n20,300,12\n22,320,12\n")
    _refused(["fit", str(tmp_path / "a12.csv"), "--amp", "3"], capsys, "a_p_deg: '12'", "--amp 3")
    path = _suite(tmp_path, "seed", lambda d: d["objects"][0].__setitem__("seed", 1.7))
    _refused(["bench", "--suite", path, "--agent", "grid", "--limit", "1", "--no-cache", "--no-progress"], capsys,
             "seed = 1.7 is not an integer")
    (tmp_path / "disc.csv").write_text("f_p_hz,omega_b_deg_s\n20,300\n22,320\n")
    _refused(["fit", str(tmp_path / "disc.csv"), "--amp", "3", "--forward", ""], capsys, "--forward ''", "choose")
    _refused(["sweep", "--physics", "atlas", "--freqs", "20", "--executor", "", "--no-progress"], capsys,
             "executor ''")
    with pytest.raises(SystemExit):  # argparse: usage and the one error line
        main(["probe", "--physics", "atlas", "--freq", "20", "--measure", "0"])
    assert "'0' is outside the allowed range (0, 600] s" in capsys.readouterr().err
    out = str(tmp_path / "cal.json")
    big = _refs(tmp_path / "big.csv", {f"d{i}": 20 * math.pi for i in range(10)}, rows_each=1000)
    _refused(["calibrate", str(big), "--amp", "3", "--out", out], capsys, "10000 rows", "at most 2000")
    same = _refs(tmp_path / "same.csv", dict.fromkeys("ABCDE", 20 * math.pi))
    _refused(["calibrate", str(same), "--amp", "3", "--out", out], capsys, "'A' and 'B' are the same disc")
    assert not Path(out).exists()


# ----------------------------------------------------------------------------------------------------- item 13
def test_item13_a_hand_edited_calibration_with_a_recomputed_hash_is_checked_value_by_value(tmp_path, capsys):
    """Member index 999 and sigma -1 in a calibration whose content hash was recomputed: refused, naming the field
    and its allowed range (5860216: IndexError, exit 3; "negative dimensions are not allowed")."""
    (tmp_path / "disc.csv").write_text("f_p_hz,omega_b_deg_s\n" + "".join(f"{f},{300 + f}\n" for f in range(14, 35)))
    edits = {"member index 999": lambda p: p["member"].__setitem__(0, 999),
             "sigma = -1.0": lambda p: p.__setitem__("sigma", [-1.0] * len(p["sigma"])),
             "a = 1000000000.0": lambda p: p["a"].__setitem__(0, 1e9)}
    for needle, edit in edits.items():
        path = _edited_paper_calibration(tmp_path, lambda d, e=edit: e(d["posterior"]))
        _refused(["fit", str(tmp_path / "disc.csv"), "--amp", "3", "--calibration", path], capsys, needle,
                 "outside the allowed range", "edited.json")
    path = _edited_paper_calibration(tmp_path, lambda d: d["known"].__setitem__("a_p_deg", "3"))
    _refused(["fit", str(tmp_path / "disc.csv"), "--amp", "3", "--calibration", path], capsys, "a_p_deg = '3'")
    assert lcf.load("paper").posterior.n_refs >= 1  # the shipped file passes every check
