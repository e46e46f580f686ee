"""Issue 37 (hardening round three) items 8 and 9: outputs replaced atomically; outputs checked before long work."""

from __future__ import annotations

import errno
import os

import numpy as np
import pytest

from plate_env.cli import main
from plate_env.core.files import write_atomic
from plate_env.core.probe_table import ProbeTable, write_lab_csv


def _full_disk(monkeypatch):
    """Every fsync fails as on a full disk (after the bytes were handed to the temporary file)."""
    def fail(fd):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(os, "fsync", fail)


def test_item8_a_failed_write_keeps_the_old_file_and_leaves_no_part(tmp_path, monkeypatch):
    out = tmp_path / "cal.json"
    out.write_text("old calibration\n")
    _full_disk(monkeypatch)
    with pytest.raises(ValueError, match="cal.json.*No space left on device.*the old file is unchanged"):
        write_atomic(out, "new" * 1000, "the calibration")
    assert out.read_text() == "old calibration\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json"]  # no temporary file left behind


def test_item8_a_sweep_csv_that_cannot_be_written_leaves_no_partial_csv(tmp_path, monkeypatch):
    t = ProbeTable.from_arrays(np.arange(10.0, 20.0), np.full(10, 3.0), np.arange(10.0), np.ones(10),
                               np.zeros(10, bool))
    out = tmp_path / "s.csv"
    _full_disk(monkeypatch)
    with pytest.raises(ValueError, match="s.csv.*nothing was written"):
        write_lab_csv(t, out)
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    write_lab_csv(t, out)
    assert out.read_text().startswith("f_p_hz,a_p_deg,omega_b_deg_s")


def test_item8_the_calibration_writer_is_atomic(tmp_path, monkeypatch):
    from plate_env.identify import lab_calibration_file as lcf

    out = tmp_path / "cal.json"
    out.write_text("old\n")
    _full_disk(monkeypatch)
    with pytest.raises(ValueError, match="the calibration '.*cal.json'"):
        lcf.save(lcf.load(lcf.PAPER), out)
    assert out.read_text() == "old\n"


@pytest.mark.parametrize("argv, needle", [
    (["build", "policy", "--out", "{tmp}"], "is a directory"),
    (["build", "policy", "--out", "{tmp}/missing/p.zip"], "does not exist"),
    (["build", "atlas", "--physics", "tilelink", "--cache-dir", "/dev/zero"], "not a folder"),
    (["build", "atlas", "--physics", "tilelink", "--out", "{tmp}"], "is a directory"),
])
def test_item9_an_output_that_cannot_be_written_is_refused_before_any_work(argv, needle, tmp_path, capsys,
                                                                           monkeypatch):
    import plate_env.build.atlas as atlas_mod

    def no_work(*a, **k):
        raise AssertionError("work started before the output was checked")
    monkeypatch.setattr(atlas_mod, "build_atlas", no_work, raising=False)
    assert main([a.format(tmp=tmp_path) for a in argv]) == 2
    assert needle in capsys.readouterr().err
