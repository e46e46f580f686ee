"""A plain table of probe outcomes, the common input of fitting and identification (from results or a lab CSV)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from plate_env.core.files import read_text, write_atomic
from plate_env.core.probe import ProbeResult


@dataclass(frozen=True)
class ProbeTable:
    """Probes in edge units: f_p (Hz), A_p (deg), omega_B and its standard error (deg/s), instability flags.

    ``omega_b_deg_s`` is sign-normalised on construction from results (multiplied by sign(A_p * B_p)) so that
    curves of either rotation direction compare with the calibration and atlas, which use A_p, B_p > 0; likewise
    ``a_p_deg`` holds the magnitude |A_p| (the constructors take the absolute value).
    """

    f_p_hz: np.ndarray
    a_p_deg: np.ndarray
    omega_b_deg_s: np.ndarray
    stderr_deg_s: np.ndarray
    unstable: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.f_p_hz)
        for name in ("a_p_deg", "omega_b_deg_s", "stderr_deg_s", "unstable"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"ProbeTable column {name} has {len(getattr(self, name))} rows, f_p_hz has {n}")

    def __len__(self) -> int:
        return len(self.f_p_hz)

    @classmethod
    def from_results(cls, results: Sequence[ProbeResult]) -> ProbeTable:
        sign = [math.copysign(1.0, r.spec.motion.amp_rad * r.spec.motion.b_p or 1.0) for r in results]
        return cls(f_p_hz=np.array([r.spec.motion.freq_hz for r in results], float),
                   a_p_deg=np.array([abs(r.spec.motion.a_p_deg) for r in results], float),
                   omega_b_deg_s=np.array([s * r.omega_b_deg_s for s, r in zip(sign, results, strict=True)], float),
                   stderr_deg_s=np.array([r.stderr_deg_s for r in results], float),
                   unstable=np.array([r.unstable for r in results], bool))

    @classmethod
    def from_arrays(cls, f_p_hz, a_p_deg, omega_b_deg_s, stderr_deg_s=None, unstable=None) -> ProbeTable:
        f = np.atleast_1d(np.asarray(f_p_hz, float))
        a = np.abs(np.broadcast_to(np.asarray(a_p_deg, float), f.shape))
        w = np.atleast_1d(np.asarray(omega_b_deg_s, float))
        se = np.zeros_like(f) if stderr_deg_s is None else np.atleast_1d(np.asarray(stderr_deg_s, float))
        un = np.zeros(f.shape, bool) if unstable is None else np.atleast_1d(np.asarray(unstable, bool))
        return cls(f, a, w, se, un)

    @classmethod
    def from_rows(cls, rows: Sequence[dict]) -> ProbeTable:
        """The inverse of :meth:`to_rows`."""
        return cls.from_arrays([r["f_p_hz"] for r in rows], [r["a_p_deg"] for r in rows],
                               [r["omega_b_deg_s"] for r in rows], [r["stderr_deg_s"] for r in rows],
                               [r["unstable"] for r in rows])

    @classmethod
    def concat(cls, *tables: ProbeTable) -> ProbeTable:
        """The probes of several tables, in order."""
        return cls(*(np.concatenate([getattr(t, f.name) for t in tables]) for f in fields(cls)))

    def subset(self, mask: np.ndarray) -> ProbeTable:
        return ProbeTable(self.f_p_hz[mask], self.a_p_deg[mask], self.omega_b_deg_s[mask], self.stderr_deg_s[mask],
                          self.unstable[mask])

    def amplitudes(self) -> list[float]:
        return sorted({float(a) for a in np.round(self.a_p_deg, 6)})

    def to_rows(self) -> list[dict]:
        """One JSON-ready dict per probe (edge units, the field names of the columns)."""
        return [{"f_p_hz": float(f), "a_p_deg": float(a), "omega_b_deg_s": float(w), "stderr_deg_s": float(s),
                 "unstable": bool(u)} for f, a, w, s, u in zip(self.f_p_hz, self.a_p_deg, self.omega_b_deg_s,
                                                               self.stderr_deg_s, self.unstable, strict=True)]


class CsvError(ValueError):
    """A malformed lab CSV: the message names the line and column."""


REQUIRED = ("f_p_hz", "omega_b_deg_s")
OPTIONAL = ("stderr_deg_s", "a_p_deg", "unstable")


def _setting(x: float) -> str:
    """A probe setting (f_p Hz, A_p deg) as written to a CSV: 12 significant digits, without float noise."""
    return repr(float(f"{float(x):.12g}"))


def write_lab_csv(table: ProbeTable, path: str | Path) -> None:
    """Write probes as the lab CSV :func:`read_lab_csv` reads (every column; an unstable probe's omega_B and stderr
    as 0, as the env records them: it has no steady rotation). Written all at once (:func:`write_atomic`): a
    failure midway leaves an existing file as it was, and the error names the file."""
    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(("f_p_hz", "a_p_deg", "omega_b_deg_s", "stderr_deg_s", "unstable"))
            for f, a, om, se, un in zip(table.f_p_hz, table.a_p_deg, table.omega_b_deg_s, table.stderr_deg_s,
                                        table.unstable, strict=True):
                # the settings as typed (12 significant digits: 3.0, not the 3.0000000000000004 a radian round trip
                # gives; issue 40 item 6); the measurements in full
                w.writerow((_setting(f), _setting(a), repr(0.0 if un else float(om)),
                            repr(0.0 if un else float(se)), int(bool(un))))

    write_atomic(path, write, "CSV")


def read_lab_csv(path: str | Path, a_p_deg: float | None = None, max_rows: int | None = None) -> ProbeTable:
    """Read a lab sweep: columns ``f_p_hz``, ``omega_b_deg_s``, optional ``stderr_deg_s``, ``a_p_deg``, ``unstable``.

    ``a_p_deg`` (the ``--amp`` option) applies to rows without their own amplitude column; with the column, both
    must agree on every row (a row the column says is at another amplitude is refused). Amplitudes are
    magnitudes, 0 < A_p <= 45 deg (``omega_b_deg_s`` sign-normalised: positive when the disc turns the way
    sign(A_p B_p) says). UTF-8 with or without a byte-order mark (Excel's "CSV UTF-8"). Raises CsvError naming the
    line and column of the first bad value; ``max_rows``: refused past that many rows, before any is parsed.
    """
    check_amp_option(a_p_deg)
    header, rows = read_csv_rows(path, max_rows)
    return sweep_table(path, header, rows, a_p_deg)


def check_amp_option(a_p_deg: float | None) -> None:
    """The ``--amp`` option: None or a magnitude in (0, 45] deg (CsvError otherwise)."""
    if a_p_deg is not None and not (isinstance(a_p_deg, (int, float)) and math.isfinite(a_p_deg)
                                    and 0 < a_p_deg <= 45):
        raise CsvError(f"plate amplitude --amp {a_p_deg!r} deg is outside the allowed range (0, 45] (the magnitude "
                       f"of A_p)")


def read_csv_rows(path: str | Path, max_rows: int | None = None) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """The header (stripped) and the data rows of a CSV, each with its line number as the messages count lines
    (blank and ``#`` comment lines left out). CsvError for an unreadable or empty file, or one of more than
    ``max_rows`` data rows (refused before a cell is parsed)."""
    try:
        text = read_text(path, "CSV", encoding="utf-8-sig")
    except ValueError as exc:
        raise CsvError(str(exc)) from None
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if max_rows is not None and len(lines) - 1 > max_rows:
        raise CsvError(f"{path}: {len(lines) - 1} rows; at most {max_rows} are read (the most a sweep makes: the "
                       "predictive check replicates every row 4000 times, and the posterior's time grows with the "
                       "distinct rows); average repeated frequencies or split the file")
    try:
        rows = list(csv.reader(lines))
    except csv.Error as exc:  # e.g. a cell past the csv module's field limit: no lab sweep has one
        raise CsvError(f"{path}: not readable as CSV: {exc} (a cell holds at most {csv.field_size_limit()} "
                       "characters)") from None
    if not rows:
        raise CsvError(f"{path}: empty file; expected a header with columns {', '.join(REQUIRED)}")
    return [h.strip() for h in rows[0]], list(enumerate(rows[1:], start=2))


def sweep_table(path: str | Path, header: list[str], rows: Sequence[tuple[int, list[str]]],
                a_p_deg: float | None = None, extra: Sequence[str] = ()) -> ProbeTable:
    """The sweep in ``rows`` (numbered as :func:`read_csv_rows` gives them), its columns checked as
    :func:`read_lab_csv` says; columns named in ``extra`` are allowed and not read (a references file's own)."""
    twice = sorted({h for h in header if header.count(h) > 1})
    if twice:
        raise CsvError(f"{path}: line 1: column(s) {twice} appear more than once; header is {header}")
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise CsvError(f"{path}: line 1: missing column(s) {', '.join(missing)}; header is {header}")
    unknown = [h for h in header if h not in REQUIRED + OPTIONAL + tuple(extra)]
    if unknown:
        raise CsvError(f"{path}: line 1: unknown column(s) {unknown}; allowed: "
                       f"{', '.join(REQUIRED + OPTIONAL + tuple(extra))}")
    if "a_p_deg" not in header and a_p_deg is None:
        raise CsvError(f"{path}: no a_p_deg column: give the plate amplitude (--amp, degrees)")
    cols: dict[str, list] = {h: [] for h in header if h not in extra}
    for lineno, row in rows:
        if len(row) != len(header):
            raise CsvError(f"{path}: line {lineno}: {len(row)} fields, the header has {len(header)}")
        for h, cell in zip(header, row, strict=True):
            if h in extra:
                continue
            cell = cell.strip()
            if h == "unstable":
                if cell.lower() not in ("0", "1", "true", "false", ""):
                    raise CsvError(f"{path}: line {lineno}, column unstable: {cell!r} is not 0/1/true/false")
                cols[h].append(cell.lower() in ("1", "true"))
                continue
            try:
                value = float(cell)
            except ValueError:
                raise CsvError(f"{path}: line {lineno}, column {h}: {cell!r} is not a number") from None
            limits = {"f_p_hz": (0.0, 200.0), "omega_b_deg_s": (-1e5, 1e5), "stderr_deg_s": (0.0, 1e5),
                      "a_p_deg": (0.0, 45.0)}[h]
            open_lo = h in ("f_p_hz", "a_p_deg")
            if not (math.isfinite(value) and limits[0] <= value <= limits[1]) or (open_lo and value == 0):
                raise CsvError(f"{path}: line {lineno}, column {h}: {cell!r} is outside the allowed range "
                               f"{'(' if open_lo else '['}{limits[0]:g}, {limits[1]:g}]")
            if h == "a_p_deg" and a_p_deg is not None and value != a_p_deg:  # neither silently wins
                raise CsvError(f"{path}: line {lineno}, column a_p_deg: {cell!r} deg, but --amp {a_p_deg:g} deg was "
                               "given: the column holds each row's amplitude; drop --amp or correct the file")
            cols[h].append(value)
    n = len(rows)
    if n == 0:
        raise CsvError(f"{path}: no data rows")
    amp = cols["a_p_deg"] if "a_p_deg" in cols else [a_p_deg] * n
    return ProbeTable.from_arrays(cols["f_p_hz"], amp, cols["omega_b_deg_s"], cols.get("stderr_deg_s"),
                                  cols.get("unstable"))
