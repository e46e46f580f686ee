"""The PyBullet sheet's stiffness -> omega_n table: ``plate-env build pybullet-table --out FILE`` writes
``plate_env/data/pybullet_calibration.json``, which :func:`plate_env.physics.pybullet_sheet.calibrate.k_for_omega_n`
interpolates for the sheet's starting stiffness.

The table is :func:`~plate_env.physics.pybullet_sheet.calibrate.measure_table` for the default
:class:`~plate_env.physics.pybullet_sheet.scene.SheetConfig` and the paper's cheese (13.6 g, 80 mm): one hang-and-
release ring-down at each stiffness of :data:`~plate_env.physics.pybullet_sheet.calibrate.K_GRID` (11 values, about
29 s of simulated time in all). The file is read as data, so the build record (command, version, commit and the
machine: PyBullet's numbers can differ in their last bits on another CPU) goes beside it, ``FILE.provenance.json``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from plate_env.core.files import write_text_atomic


def build_pybullet_table(out: str | Path, record: dict) -> dict:
    """Measure the table for the default sheet and the paper's cheese, write it to ``out`` and the build record
    (with the machine and pybullet's version) to ``out`` + ``.provenance.json``; returns the table. Nothing is
    written before the measurement finishes."""
    import pybullet

    from plate_env.build.provenance import machine
    from plate_env.physics.pybullet_sheet.calibrate import measure_table, table_text
    from plate_env.physics.pybullet_sheet.scene import SheetConfig

    out = Path(out)
    if out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a directory: give the file to write")
    table = measure_table(SheetConfig())
    write_text_atomic(out, table_text(table), "--out")
    record = {**record, "artifact": "pybullet-table",
              "inputs": "measure_table(SheetConfig()) for ObjectSpec() (13.6 g, 80 mm), "
                        "plate_env.physics.pybullet_sheet.calibrate",
              "machine": {**machine(), "pybullet_api": getattr(pybullet, "getAPIVersion", lambda: None)()}}
    write_text_atomic(f"{out}.provenance.json", json.dumps(record, indent=1) + "\n", "build record")
    return table


__all__: Sequence[str] = ("build_pybullet_table",)
