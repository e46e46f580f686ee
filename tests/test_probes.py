"""The probe table and the lab CSV reader (plate_env.probes): every malformed file is one clear error."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from plate_env.core.probe_table import CsvError, ProbeTable, read_lab_csv

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])


def _write(tmp_path, text):
    p = tmp_path / "lab.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, message", [
    ("f_p_hz,omega\n10,1\n", "missing column(s) omega_b_deg_s"),
    ("f_p_hz,omega_b_deg_s\n10,abc\n", "line 2, column omega_b_deg_s"),
    ("f_p_hz,omega_b_deg_s\n10,1\n-3,4\n", "line 3, column f_p_hz"),
    ("f_p_hz,omega_b_deg_s\n10,1,2\n", "line 2: 3 fields"),
    ("f_p_hz,omega_b_deg_s,stderr_deg_s\n10,1,nan\n", "line 2, column stderr_deg_s"),
    ("", "empty file"),
    ("f_p_hz,omega_b_deg_s\n", "no data rows"),
])
def test_csv_errors_name_line_and_column(tmp_path, text, message):
    with pytest.raises(CsvError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_lab_csv(_write(tmp_path, text), a_p_deg=3.0)


def test_csv_needs_an_amplitude(tmp_path):
    with pytest.raises(CsvError, match="--amp"):
        read_lab_csv(_write(tmp_path, "f_p_hz,omega_b_deg_s\n10,1\n"))


CELLS = st.sampled_from(["10", "25.5", "-3", "0", "nan", "inf", "1e9", "abc", "", " 12 ", "true", "1", "0.0",
                         "300", '"7"', "3;4"])


HEADERS = st.lists(st.sampled_from(["f_p_hz", "omega_b_deg_s", "stderr_deg_s", "a_p_deg", "unstable", "junk", ""]),
                   min_size=0, max_size=5)


@st.composite
def csv_text(draw) -> str:
    """Random CSV-ish text: a random header and rows of random cells, or plain random text."""
    if draw(st.booleans()):
        return draw(st.text(max_size=200))
    header = draw(HEADERS)
    rows = [",".join(draw(st.lists(CELLS, min_size=0, max_size=len(header) + 1)))
            for _ in range(draw(st.integers(0, 6)))]
    comment = ["# a comment"] if draw(st.booleans()) else []
    return "\n".join(comment + [",".join(header)] + rows)


@FAST
@given(text=csv_text(), amp=st.sampled_from([None, 3.0, 12.0]))
def test_csv_reader_table_or_csverror(tmp_path, text, amp):
    path = tmp_path / "lab.csv"
    path.write_text(text, encoding="utf-8")
    try:
        table = read_lab_csv(path, a_p_deg=amp)
    except CsvError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    assert isinstance(table, ProbeTable) and len(table) > 0
    for col in (table.f_p_hz, table.a_p_deg, table.omega_b_deg_s, table.stderr_deg_s):
        assert np.all(np.isfinite(col))


def test_csv_reader_binary_file(tmp_path):
    path = tmp_path / "bin.csv"
    path.write_bytes(b"\xff\xfe\x00\x01garbage")
    with pytest.raises(CsvError):
        read_lab_csv(path, a_p_deg=3.0)


def test_rows_round_trip_and_concat_keeps_every_column_in_order():
    from plate_env.core.probe_table import ProbeTable

    a = ProbeTable.from_arrays([10.0, 11.0], 3.0, [100.0, 0.0], [1.0, 0.0], [False, True])
    b = ProbeTable.from_arrays([12.0], 12.0, [50.0], [2.0], [False])
    back = ProbeTable.from_rows(a.to_rows())
    assert back.to_rows() == a.to_rows() and back.unstable.dtype == bool
    both = ProbeTable.concat(a, b)
    assert both.to_rows() == a.to_rows() + b.to_rows()
