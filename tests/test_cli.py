"""The plate-env command line, all of it here: each command's output and JSON schema, plots, and bad input as one
clear line, never a traceback (a property test over random command lines on the atlas backend)."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import plate_env  # noqa: F401
from plate_env.cli import main
from plate_env.identify.calibration import (
    paper_calibration,
)
from plate_env.identify.fitting import lorentzian


def test_probe_json_round_trip(capsys):
    assert main(["probe", "--omega-n", "10pi", "--alpha", "36.9", "--freq", "25", "--amp", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["physics"] == "tilelink"
    assert out["f_p_hz"] == 25.0 and out["a_p_deg"] == pytest.approx(3.0)
    assert out["omega_n_rad_s"] == pytest.approx(31.4159, rel=1e-4)
    assert out["omega_b_deg_s"] > 100 and out["unstable"] is False


def test_sweep_json_and_plot(tmp_path, capsys):
    png = tmp_path / "sweep.png"
    assert main(["sweep", "--object", "cheese", "--freqs", "12,25", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [p["f_p_hz"] for p in out["probes"]] == [12.0, 25.0]
    assert png.stat().st_size > 5000


@pytest.mark.parametrize("argv, message", [
    (["probe", "--omega-n", "abc", "--freq", "25"], "omega_n"),
    (["sweep", "--freqs", "40:10:1"], "--freqs"),
    (["probe", "--freq", "nan"], "--freq"),
    (["probe", "--freq", "25", "--object", "pizza"], "unknown object preset"),
    # B_p is a known input of identify: the atlas physics (built at 3 mm) refuses another one by name
    (["identify", "--physics", "atlas", "--omega-n", "12pi", "--bp", "2"], "B_p = 2 mm"),
    (["identify", "--omega-n", "12pi", "--bp", "1e6"], "--bp"),
    (["identify", "--omega-n", "12pi", "--bp", "1"], "no tilelink/pointmass atlas for B_p = 1 mm"),
])
def test_bad_input_is_one_clear_line(argv, message, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # refused by argparse while parsing: its usage line, then the one-line error
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_python_m_entry_point():
    out = subprocess.run([sys.executable, "-m", "plate_env", "probe", "--freq", "12", "--json"],
                         capture_output=True, text=True, check=True).stdout
    assert json.loads(out)["f_p_hz"] == 12.0


FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])


NUMBERS = st.sampled_from(["0", "-1", "3", "25", "12.5", "1e3", "nan", "inf", "-inf", "1e-9", "abc", "", "10pi",
                           "3.5pi", "pi", "--", "0x10", "1,2", "10:40:1", "40:10:1", "10:40:0", "5:6:0.5", "é",
                           "-10pi", "-0", "1e309", "-1e-3", "1e-300", "2e9"])


OPTIONS = ("--object", "--omega-n", "--alpha", "--mass-g", "--amp", "--bp", "--settle", "--measure", "--freq",
           "--freqs", "--method", "--model", "--json", "--no-progress", "--bogus", "-h", "--seed", "--max-probes",
           "--target", "--agent", "--plot")


OBJECTS = st.sampled_from(["cheese", "dumpling", "cheese_lead", "pizza", ""])
#: Signed integers, from small to far beyond any int64 (seeds, budgets).
INTEGERS = st.integers(-2 ** 70, 2 ** 70).map(str)
#: Frequency ranges start:stop:step with tiny steps and huge spans (a probe count of 1e14 must not be allocated).
FREQ_RANGES = st.builds(lambda a, b, c: f"{a:g}:{b:g}:{c:g}", st.floats(-10.0, 300.0), st.floats(-10.0, 1e6),
                        st.one_of(st.floats(1e-15, 1e-3), st.floats(-1.0, 50.0)))
PLOTS = st.sampled_from(["/nonexistent/x.png", "/tmp", "", "plot.bogus", "/dev/null/x.png"])


@st.composite
def cli_argv(draw) -> list[str]:
    """A random command line: a (possibly unknown) command, atlas physics, random options and values.

    ``identify`` always gets a signed integer ``--seed`` and a small or absurd ``--max-probes`` (the default 30
    probes would make an example slow); ``sweep`` a generated ``--freqs``. ``--dt`` is left out (it does not apply
    to atlas physics: ``test_cli_atlas_with_dt_is_a_clear_error``; on live physics see test_bad_input.py), and
    frequencies below 1 Hz are not drawn for live physics (a 2-period probe at 1e-6 Hz lasts 2e6 simulated s).
    ``--plot`` paths are ones that must be refused before any work (none is written)."""
    cmd = draw(st.sampled_from(["probe", "sweep", "fit", "identify", "identify", "bogus", ""]))
    argv = [cmd] if cmd else []
    if cmd in ("probe", "sweep", "identify"):
        argv += ["--physics", draw(st.sampled_from(["atlas", "atlas", "nonsense"]))]
    if cmd == "fit":
        argv.append(draw(st.sampled_from(["/nonexistent.csv", "/tmp", "/dev/null"])))
    if cmd == "identify":
        argv += ["--seed", draw(INTEGERS), "--max-probes", draw(st.sampled_from(["2", "3", "0", "-1", "1e9", "2.5"])),
                 "--agent", draw(st.sampled_from(["grid", "coarse_to_fine", "bayes", "magic"]))]
    if cmd == "sweep":
        argv += ["--freqs", draw(FREQ_RANGES)]
    for _ in range(draw(st.integers(0, 6))):
        opt = draw(st.sampled_from(OPTIONS))
        if opt == "-h":
            continue  # help exits 0 via SystemExit: checked separately
        argv.append(opt)
        if opt in ("--json", "--no-progress"):
            continue
        if opt == "--object":
            argv.append(draw(OBJECTS))
        elif opt == "--method":
            argv.append(draw(st.sampled_from(["lorentz", "atlas", "magic"])))
        elif opt == "--model":
            argv.append(draw(st.sampled_from(["pointmass", "rigid", "foo"])))
        elif opt == "--agent":
            argv.append(draw(st.sampled_from(["grid", "bayes", "magic"])))
        elif opt == "--plot":
            argv.append(draw(PLOTS))
        elif opt in ("--seed", "--max-probes"):
            argv.append(draw(INTEGERS))
        elif opt == "--freqs":
            argv.append(draw(st.one_of(FREQ_RANGES, NUMBERS)))
        elif draw(st.booleans()):
            argv.append(draw(NUMBERS))
    return argv


def _run_cli(argv: Sequence[str], capsys) -> tuple[int, str]:
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse: usage errors exit 2, --help exits 0
        code = exc.code if isinstance(exc.code, int) else 2
    except BaseException as exc:  # noqa: BLE001 - what a user would see as a traceback
        code, err = -1, f"Traceback: {type(exc).__name__}: {exc}"
        return code, capsys.readouterr().err + err
    return code, capsys.readouterr().err


@settings(FAST, max_examples=100, derandomize=True)  # derandomized: the same examples on every run
@given(argv=cli_argv())
def test_cli_never_tracebacks(argv, capsys):
    code, err = _run_cli(argv, capsys)
    assert code in (0, 1, 2), (argv, code, err)  # 1: fit/identify ran but gave no estimate (documented)
    assert "Traceback" not in err
    if code == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert lines and "error" in lines[-1], (argv, err)
        # our own errors are one line; argparse adds its usage line before the error line
        assert len(lines) <= 2 or lines[0].startswith("usage:"), (argv, err)


def test_cli_help_exits_zero(capsys):
    assert _run_cli(["probe", "-h"], capsys)[0] == 0


@pytest.mark.parametrize("physics", ["atlas", "tilelink"])
def test_cli_zero_frequency_is_a_clear_error(physics, capsys):
    code, err = _run_cli(["probe", "--physics", physics, "--freq", "0"], capsys)
    assert code == 2 and "Traceback" not in err


def test_cli_atlas_with_dt_is_a_clear_error(capsys):
    code, err = _run_cli(["probe", "--physics", "atlas", "--dt", "1e-3", "--freq", "25"], capsys)
    assert code == 2 and "Traceback" not in err and "--dt" in err


def test_cli_tiny_frequency_is_refused_not_simulated_for_hours(capsys):
    code, err = _run_cli(["probe", "--freq", "1e-6"], capsys)
    assert code == 2 and "--freq" in err and "[0.5, 200] Hz" in err


def test_fit_refuses_a_nan_amplitude(tmp_path, capsys):
    path = tmp_path / "lab.csv"
    path.write_text("f_p_hz,omega_b_deg_s\n10,1\n12,3\n")
    code, err = _run_cli(["fit", str(path), "--amp", "nan"], capsys)
    assert code == 2 and "--amp" in err


def test_cli_fit_json_and_plot(tmp_path, capsys):
    f = np.arange(8.0, 18.01, 1.0)
    y = lorentzian(f, 380.0, 13.0, 2.5)
    p = _write_csv(tmp_path, "f_p_hz,omega_b_deg_s,stderr_deg_s\n" + "".join(f"{a},{b},5\n" for a, b in zip(f, y,
                                                                                                   strict=True)))
    png = tmp_path / "fit.png"
    assert main(["fit", str(p), "--amp", "12", "--method", "lorentz", "--physics", "paper", "--json", "--plot",
                 str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] and out["fits"]["12"]["f0_hz"] == pytest.approx(13.0, rel=1e-3)
    assert out["omega_n_rad_s"] == pytest.approx(paper_calibration(12).omega_n(13.0), rel=1e-3)
    assert png.stat().st_size > 5000
    assert main(["fit", str(tmp_path / "missing.csv"), "--amp", "3"]) == 2


def _write_csv(tmp_path, text):
    p = tmp_path / "lab.csv"
    p.write_text(text)
    return p


def test_identify_json_schema(capsys):
    code = main(["identify", "--agent", "grid", "--physics", "tilelink", "--omega-n", "17pi", "--alpha", "45",
                 "--seed", "0", "--max-probes", "8", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code in (0, 1)
    for key in ("agent", "omega_n_true_rad_s", "alpha_true_deg", "relative_error", "n_probes", "sim_s", "wall_s",
                "estimate", "probes"):
        assert key in out
    assert out["n_probes"] == len(out["probes"]) == 8
    assert set(out["estimate"]) >= {"ok", "omega_n_rad_s", "omega_n_stderr_rad_s", "method"}
    assert out["omega_n_true_rad_s"] == pytest.approx(17 * math.pi)


def _all_parsers():
    import argparse

    from plate_env.cli import build_parser

    out, todo = [], [("plate-env", build_parser())]
    while todo:
        name, p = todo.pop()
        out.append((name, p))
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                todo += [(f"{name} {k}", sp) for k, sp in a.choices.items()]
    return out


def test_every_option_with_a_default_shows_it_in_every_subcommand_help():
    """Issue 40 item 5: --seed's default 0 was hidden (0 == False) and build's subcommands showed none."""
    import argparse

    checked = 0
    for name, p in _all_parsers():
        text = " ".join(p.format_help().split())
        for a in p._actions:
            d = a.default
            if (not a.option_strings or d is None or d is False or d is argparse.SUPPRESS or d == []
                    or isinstance(a, (argparse._StoreTrueAction, argparse._HelpAction))):
                continue
            flag = a.option_strings[-1]
            block = text.split(flag, 2)[-1][:400]  # the option's own help follows its flags in the listing
            assert f"(default: {d})" in block or "default" in (a.help or ""), (name, flag, d)
            checked += 1
    assert checked > 30


def test_help_lists_the_tilelink_models_the_code_has_and_names_no_missing_script():
    from plate_env.cli import TILELINK_MODELS_HELP
    from plate_env.physics.tilelink.backend import MODELS

    assert TILELINK_MODELS_HELP == ", ".join(MODELS)
    for name, p in _all_parsers():
        assert "experiments/leaderboard.py" not in p.format_help(), name


def test_a_sweep_csv_writes_the_settings_as_typed(tmp_path):
    """Issue 40 item 6: ``a_p_deg`` was written as 3.0000000000000004 (a radian round trip)."""
    import csv

    from plate_env.cli import main

    out = tmp_path / "s.csv"
    assert main(["sweep", "--physics", "atlas", "--omega-n", "17pi", "--alpha", "45", "--freqs", "10:12:0.1",
                 "--csv", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert {r["a_p_deg"] for r in rows} == {"3.0"}
    assert [r["f_p_hz"] for r in rows][:4] == ["10.0", "10.1", "10.2", "10.3"]


#: A path-like token of a help text: directories and a file or directory name (``experiments/leaderboard.py``).
_HELP_PATH = re.compile(r"(?<![\w/.<>-])((?:[A-Za-z_][\w.-]*/)+[\w.-]+)")
#: Tokens with a slash that are not paths: a physics/model name, units, a placeholder (``path/to/file.py``).
_NOT_A_PATH = ("rad/s", "joint/contact", "path/to/", "tilelink/", "pybullet/", "object/", "lab/", "CACHE_DIR/")


def test_no_help_text_names_a_path_that_does_not_exist():
    """Issue 40 item 5: ``bench --help`` named experiments/leaderboard.py, which does not exist. Every path a help
    text names is a file or directory of the repository or of an installed package (plate_env, plate_env_agents)."""
    from pathlib import Path

    import plate_env_agents

    repo = Path(plate_env.__file__).parent.parent
    # an installed package's path names its own folder (plate_env_agents is the repository's agents/ folder)
    packages = {"plate_env": Path(plate_env.__file__).parent,
                "plate_env_agents": Path(plate_env_agents.__file__).parent}

    def exists(token: str) -> bool:
        top, _, rest = token.partition("/")
        return (repo / token).exists() or (top in packages and (packages[top] / rest).exists())

    named = set()
    for name, p in _all_parsers():
        text = p.format_help()
        for token in _HELP_PATH.findall(text):
            token = token.rstrip(".")
            if token.startswith(_NOT_A_PATH) or "<" in token:
                continue
            named.add(token)
            assert exists(token), f"{name} --help names {token!r}, which does not exist"
    assert {"plate_env/data/grids", "plate_env_agents/hyperparams/ppo.yml"} <= named  # the scan sees paths


def _numeric_kind(action) -> str | None:
    """'int' or 'real' for an option whose value is a number (its ``type``), else None."""
    from plate_env.cli.options import omega_n_arg
    from plate_env.core import checks

    t = action.type
    if t is int or t is float or t is omega_n_arg:
        return "int" if t is int else "real"
    cells = [c.cell_contents for c in (getattr(t, "__closure__", None) or ())]
    if checks.integer in cells:
        return "int"
    return "real" if checks.real in cells else None


_UNIT = re.compile(r"\b(Hz|deg|degrees|mm|g|grams|s|seconds|rad/s|fraction)\b")


def test_every_numeric_option_states_its_default_and_its_unit():
    """Issue 40 item 5: ``identify --help`` showed no default for --object, --omega-n, --alpha, --mass-g (None:
    the preset's value, else the custom disc's, said nowhere), nor for --target, bench --limit, fit/calibrate
    --amp. Every numeric option's help states its default (argparse's ``(default: X)`` or its own words), and every
    real-valued one a unit (or ``fraction``)."""
    import argparse

    checked = 0
    for name, p in _all_parsers():
        text = " ".join(p.format_help().split())
        for a in p._actions:
            kind = _numeric_kind(a)
            if kind is None or not a.option_strings or a.required:
                continue
            flag = a.option_strings[-1]
            block = text.split(f"{flag} {a.metavar or a.dest.upper()} ", 2)[-1][:500]
            own = block.split(" --", 1)[0]  # up to the next option's flags
            assert "default" in own, f"{name} {flag}: no default in its help: {own!r}"
            if kind == "real":
                assert _UNIT.search(own), f"{name} {flag}: a number without its unit: {own!r}"
            checked += 1
            assert not isinstance(a, argparse._StoreTrueAction)
    assert checked > 40
    # the words are true: an option not given takes the custom disc's value (plate_env.core.objects.ObjectSpec)
    from plate_env.core.objects import ObjectSpec

    ident = " ".join(next(p for n, p in _all_parsers() if n == "plate-env identify").format_help().split())
    assert f"else {ObjectSpec().omega_n / math.pi:g}pi" in ident and f"else {ObjectSpec().mass * 1e3:g})" in ident


def test_fit_json_names_what_read_the_data_once(capsys):
    """Issue 40 item 5: ``fit --forward tilelink/pointmass --json`` reported ``"physics": "lab", "model": "lab"``
    (the Lorentz method's unused defaults) beside ``"forward"``."""
    from pathlib import Path

    csv = str(Path(__file__).parent.parent / "examples" / "cheese_sweep.csv")
    assert main(["fit", csv, "--amp", "3", "--forward", "tilelink/pointmass", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["forward"] == "tilelink/pointmass" and "physics" not in out and "model" not in out
    assert main(["fit", csv, "--amp", "3", "--method", "lorentz", "--physics", "tilelink", "--json"]) in (0, 1)
    out = json.loads(capsys.readouterr().out)
    assert (out["physics"], out["model"], out["forward"]) == ("tilelink", "pointmass", None)
