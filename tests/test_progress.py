"""Issue 40 item 3: progress outside a terminal is a few plain lines, not a bar's every redraw."""

from __future__ import annotations

from plate_env.cli import main


def test_a_sweep_into_a_file_prints_a_few_plain_progress_lines(capsys):
    assert main(["sweep", "--physics", "atlas", "--omega-n", "17pi", "--alpha", "45", "--freqs", "10:40:0.5"]) == 0
    err = capsys.readouterr().err  # pytest's capture is not a terminal, as a log file or a pipe is not
    lines = [ln for ln in err.splitlines() if "/61 probes" in ln]
    assert "\r" not in err and "%|" not in err  # no bar redraws
    assert 2 <= len(lines) <= 11 and lines[-1].endswith("61/61 probes")


def test_plain_progress_counts_tenths_and_the_end(capsys):
    from plate_env.core.progress import PlainProgress

    p = PlainProgress(100, "x", "probe")
    for _ in range(100):
        p.update()
    p.close()
    p.close()
    got = capsys.readouterr().err.splitlines()
    assert got == [f"x: {k}/100 probes" for k in range(10, 100, 10)] + ["x: 100/100 probes"]



def test_every_command_that_shows_probe_progress_takes_no_progress(capsys, tmp_path):
    """Issue 40 item 3 ('--no-progress everywhere'): the commands that run probes behind a progress bar (sweep,
    bench, build atlas, build calibration eq10) all take --no-progress, and it silences the bar: a small atlas build
    prints its progress lines without it and none with it."""
    import argparse

    from plate_env.cli import build_parser

    def sub(p, name):
        return next(a for a in p._actions if isinstance(a, argparse._SubParsersAction)).choices[name]

    parser = build_parser()
    build = sub(parser, "build")
    for name, p in (("sweep", sub(parser, "sweep")), ("bench", sub(parser, "bench")),
                    ("build atlas", sub(build, "atlas")), ("build calibration", sub(build, "calibration"))):
        assert any("--no-progress" in a.option_strings for a in p._actions), name
    build = ["build", "atlas", "--select", "omega_n_pi=10.464", "--select", "alpha_deg=44", "--select", "a_p_deg=3",
             "--repeats", "1", "--held-out", "0", "--cache-dir", str(tmp_path)]
    assert main([*build, "--out", str(tmp_path / "a.npz")]) == 0
    with_bar = capsys.readouterr().err
    assert main([*build, "--out", str(tmp_path / "b.npz"), "--cache-dir", str(tmp_path / "fresh"),
                 "--no-progress"]) == 0
    without = capsys.readouterr().err
    assert "atlas" in with_bar and "/" in with_bar  # plain progress lines, "atlas: k/n ..."
    assert not [line for line in without.splitlines() if "/" in line and "atlas" in line]
