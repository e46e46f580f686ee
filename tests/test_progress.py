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

