"""The paper calibration's builder: ``plate-env build calibration paper --out FILE`` writes
``plate_env/data/calibration_paper.json`` (``--calibration paper``) from the paper's published numbers at
A_p = 3 deg, through the public calibration function (:func:`plate_env.identify.lab_calibration_file.calibrate`),
so it follows any change to the calibration's method or schema.

The references are one curve per Table 1 object: omega_Brmax from Table 1, f0 from Eq. (10) solved for f0
(omega_n [pi rad/s] = p1 f0 + q1), a half-width b between the 5.1 and 5.8 Hz the paper publishes, sampled at 14-34 Hz
(1 Hz) with a standard error of :data:`PAPER_STDERR` per point. The file records the commit that wrote it inside
its hashed body (the calibration's schema), so a rebuild at another commit differs in ``commit`` and
``content_sha256`` only; the build record goes beside it, ``FILE.provenance.json``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from plate_env.core.files import write_text_atomic
from plate_env.core.probe_table import ProbeTable
from plate_env.identify.fitting import lorentzian

#: The paper's Eq. (10) at A_p = 3 deg: omega_n [pi rad/s] = PAPER_P1 * f0 [Hz] + PAPER_Q1.
PAPER_P1, PAPER_Q1 = 5.30, -121.62
#: Table 1 at 3 deg: (omega_n [pi rad/s], omega_Brmax [deg/s]).
PAPER_TABLE1_3DEG = ((3.5, 491.5), (10.0, 614.9), (23.0, 722.8), (33.0, 796.1))
#: The half-widths b the paper publishes (Hz), at 10pi and 33pi.
PAPER_B_HZ = (5.1, 5.8)
#: The frequencies of a reference curve (Hz).
PAPER_F_HZ = tuple(float(f) for f in range(14, 35))
#: Standard error per point, deg/s: the paper gives none; its curves are fits with R^2 0.98-0.99.
PAPER_STDERR = 10.0
#: The amplitude the paper's Eq. (10) and Table 1 hold at (deg).
PAPER_A_P_DEG = 3.0
#: What ``plate-env build calibration`` builds here (``eq10``: :mod:`plate_env.build.eq10`).
CALIBRATIONS = ("paper",)


def paper_curve(omega_max: float, f0: float, b: float) -> ProbeTable:
    """A reference sweep: the Lorentzian (``omega_max`` deg/s, ``f0`` Hz, ``b`` Hz) at :data:`PAPER_F_HZ`, 3 deg."""
    f = np.array(PAPER_F_HZ)
    return ProbeTable.from_arrays(f, np.full(f.size, PAPER_A_P_DEG), lorentzian(f, omega_max, f0, b),
                                  np.full(f.size, PAPER_STDERR), np.zeros(f.size, bool))


def paper_b(w_pi: float) -> float:
    """b (Hz) interpolated in log omega_n between the paper's 5.1 Hz (10pi) and 5.8 Hz (33pi), held inside that
    band."""
    t = (math.log(w_pi) - math.log(10.0)) / (math.log(33.0) - math.log(10.0))
    return float(np.clip(PAPER_B_HZ[0] + (PAPER_B_HZ[1] - PAPER_B_HZ[0]) * t, *PAPER_B_HZ))


def paper_references() -> list[tuple[float, float, float, float]]:
    """``(omega_n pi rad/s, omega_Brmax deg/s, f0 Hz, b Hz)`` of each Table 1 object at 3 deg."""
    return [(w, wm, (w - PAPER_Q1) / PAPER_P1, paper_b(w)) for w, wm in PAPER_TABLE1_3DEG]


def paper_calibration():
    """The :class:`~plate_env.identify.lab_calibration_file.LabCalibration` of the paper's numbers (forward model
    ``lab``, the paper's set-up)."""
    from plate_env.identify import lab_calibration_file as lcf
    from plate_env.surrogate.conditioning import KnownInputs

    refs = paper_references()
    return lcf.calibrate([paper_curve(wm, f0, b) for _, wm, f0, b in refs], [w * math.pi for w, *_ in refs],
                         [f"Table 1, {w:g}pi" for w, *_ in refs], PAPER_A_P_DEG, KnownInputs())


def build_calibration(name: str, out: str | Path, record: dict) -> dict:
    """Write calibration ``name`` (:data:`CALIBRATIONS`) to ``out`` and the build record to ``out`` +
    ``.provenance.json``; returns the calibration's JSON. ValueError for another name, before any work."""
    if name not in CALIBRATIONS:
        raise ValueError(f"unknown calibration {name!r}; this package builds {[*CALIBRATIONS, 'eq10']}")
    from plate_env.identify import lab_calibration_file as lcf

    cal = paper_calibration()
    lcf.save(cal, out)
    body = json.loads(Path(out).read_text())
    record = {**record, "artifact": f"calibration {name}", "content_sha256": body.get("content_sha256"),
              "inputs": "the paper's Eq. (10), Table 1 and half-widths at 3 deg (plate_env.build.calibration)"}
    write_text_atomic(f"{out}.provenance.json", json.dumps(record, indent=1) + "\n", "build record")
    return body


__all__: Sequence[str] = ("CALIBRATIONS", "PAPER_A_P_DEG", "PAPER_B_HZ", "PAPER_F_HZ", "PAPER_P1", "PAPER_Q1",
                          "PAPER_STDERR", "PAPER_TABLE1_3DEG", "build_calibration", "paper_b", "paper_calibration",
                          "paper_curve", "paper_references")
