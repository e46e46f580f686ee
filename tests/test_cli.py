"""The plate-env command line."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from plate_env.cli import main


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
