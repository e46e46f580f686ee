"""``plate-env build pybullet-table`` and ``plate-env build calibration eq10``: the shipped PyBullet stiffness table
and Eq. (10) lines rebuilt from the installed package (and, for the lab line, committed sweeps)."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import pytest
from cross_cpu import assert_close

from plate_env.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _shipped(name: str) -> bytes:
    return (resources.files("plate_env") / "data" / name).read_bytes()


def _record_ok(record: dict, argv: list[str], artifact: str) -> None:
    from plate_env.identify.lab_calibration_file import package_version

    assert record["command"] == "plate-env build " + " ".join(argv)
    assert record["plate_env"] == package_version() != "unknown"
    assert record["artifact"] == artifact
    assert {"numba_cpu", "blas", "numpy", "numba"} <= set(record["machine"])


# --------------------------------------------------------------------------------------------------- pybullet-table
def test_shipped_pybullet_table_is_the_measured_table_of_the_default_sheet_in_the_builders_layout():
    """The schema: the default SheetConfig's keys and values, the paper's cheese, the stiffness grid, and the text
    the builder writes for it (so a rebuild can equal it byte for byte)."""
    pytest.importorskip("pybullet")
    from plate_env.core.objects import ObjectSpec
    from plate_env.physics.pybullet_sheet.calibrate import K_GRID, _config_key, stored_table, table_text
    from plate_env.physics.pybullet_sheet.scene import SheetConfig

    table = stored_table()
    assert table["config"] == _config_key(SheetConfig())
    assert (table["mass"], table["diameter"]) == (ObjectSpec().mass, ObjectSpec().diameter)
    assert table["k_elastic"] == list(K_GRID) and len(table["omega_n"]) == len(K_GRID)
    assert table_text(table).encode() == _shipped("pybullet_calibration.json")


@pytest.mark.parametrize("k", [100.0, 400.0])
def test_a_ringdown_of_the_builder_equals_the_shipped_tables_entry_bit_for_bit(k):
    """Two of the table's 11 ring-downs (about 2 s each), each in a fresh client as the builder runs them in one:
    the same omega_n to the last bit (on this machine: PyBullet's last bits may depend on the CPU)."""
    pytest.importorskip("pybullet")
    from plate_env.physics.pybullet_sheet.calibrate import measure_table, stored_table
    from plate_env.physics.pybullet_sheet.scene import SheetConfig

    shipped = stored_table()
    built = measure_table(SheetConfig(), k_grid=(k,))
    assert built["omega_n"] == [shipped["omega_n"][shipped["k_elastic"].index(k)]]


@pytest.mark.slow
def test_build_pybullet_table_writes_the_shipped_table_byte_for_byte(tmp_path):
    """The whole table: 11 ring-downs, about 20 s."""
    pytest.importorskip("pybullet")
    out = tmp_path / "pybullet_calibration.json"
    argv = ["pybullet-table", "--out", str(out)]
    assert main(["build", *argv]) == 0
    assert out.read_bytes() == _shipped("pybullet_calibration.json")
    record = json.loads(Path(f"{out}.provenance.json").read_text())
    _record_ok(record, argv, "pybullet-table")
    assert record["machine"]["pybullet_api"]


def test_build_pybullet_table_refuses_a_directory_before_any_ringdown(tmp_path, capsys):
    assert main(["build", "pybullet-table", "--out", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err
    assert not Path(f"{tmp_path}.provenance.json").exists()


def test_the_old_table_script_names_the_builder():
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "plate_env.physics.pybullet_sheet.calibrate"], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 1 and "plate-env build pybullet-table" in run.stderr
    assert not run.stdout


# --------------------------------------------------------------------------------------------------- calibration eq10
CACHE = ROOT / "experiments" / "cache"
RIGID = "tilelink/rigid_fast/3"
SIMULATED = ("sweeps_tilelink_pointmass.jsonl", "evalnuis_tilelink_pointmass_A3_s400.jsonl")


def _eq10(tmp_path, sweeps: Path, lab_sweeps: Path = CACHE) -> tuple[list[str], Path]:
    out = tmp_path / "calibration.json"
    return ["calibration", "eq10", "--sweeps", str(sweeps), "--lab-sweeps", str(lab_sweeps), "--out", str(out)], out


def _committed_sweeps(tmp_path) -> Path:
    sweeps = tmp_path / "sweeps"
    sweeps.mkdir()
    for name in SIMULATED:
        (sweeps / name).write_bytes((CACHE / name).read_bytes())
    return sweeps


def test_build_calibration_eq10_from_the_committed_sweeps_equals_the_recorded_rebuild(tmp_path):
    """From the committed sweeps (no probe simulated: the caches are unchanged), the point-mass and lab lines equal
    the rebuild recorded in experiments/results/eq10_rebuild.json bit for bit, in the shipped file's schema (the
    shipped ones differ as that study explains, see docs/build.md); the faithful physics' line, fitted from its
    committed input sweeps, equals the shipped one."""
    from plate_env.identify.calibration import load_calibrations

    sweeps = _committed_sweeps(tmp_path)
    argv, out = _eq10(tmp_path, sweeps)
    assert main(["build", *argv]) == 0
    assert all((sweeps / n).read_bytes() == (CACHE / n).read_bytes() for n in SIMULATED)  # nothing simulated
    built = json.loads(out.read_text())
    study = json.loads((ROOT / "experiments" / "results" / "eq10_rebuild.json").read_text())
    shipped = json.loads(_shipped("calibration.json"))
    assert_close({k: v for k, v in built.items() if k != RIGID}, study["rebuilt"])  # bit for bit where recorded
    assert_close(built[RIGID], shipped[RIGID])
    assert built.keys() == shipped.keys() == {"lab/lab/3", "tilelink/pointmass/3", "tilelink/pointmass/12", RIGID}
    for key in built:
        assert built[key].keys() == shipped[key].keys()
        # provenance: the build command in place of the script and date (those go to the build record; the
        # faithful line was made by the builder)
        extra = {"date", "plate_env", "script", "build"}
        assert set(built[key]["provenance"]) - {"build"} == set(shipped[key]["provenance"]) - extra
        assert built[key]["provenance"]["build"] == "plate-env build calibration eq10"
    assert {k: c.n for k, c in load_calibrations(out).items()} == {k: v["n"] for k, v in built.items()}
    record = json.loads(Path(f"{out}.provenance.json").read_text())
    _record_ok(record, argv, "calibration eq10")
    assert record["inputs"]["read"]["pybullet"].endswith("eval_pybullet_pybullet_A3_s600.jsonl")
    assert record["inputs"]["read"]["rigid_fast"].endswith("atlas_faithful.jsonl")


def test_the_faithful_line_is_read_from_the_faithful_atlas_probes_frozen_as_an_input():
    """The tilelink/rigid_fast/3 line (issue 33): the first-hump f0 of the faithful atlas's 3-deg sweeps (120 of them:
    the omega_n nodes in the calibration objects' range x 5 alpha x 2 repeats, B_p 3 mm) with the friction model,
    read from the frozen input, whose records are the committed atlas cache's; fitted again from them it is the
    shipped line."""
    from plate_env.build.eq10 import RIGID_FAST_CACHE, missing_rigid_fast_probes, rigid_fast_line, rigid_fast_specs
    from plate_env.build.provenance import inputs_dir
    from plate_env.identify.calibration import get_calibration

    frozen = inputs_dir() / RIGID_FAST_CACHE
    lines = frozen.read_text().splitlines()
    assert len(lines) == len(rigid_fast_specs()) == 31 * 12 * 5 * 2
    assert set(lines) <= set((CACHE / RIGID_FAST_CACHE).read_text().splitlines())
    assert missing_rigid_fast_probes(inputs_dir()) == 0
    cal = get_calibration("tilelink", "rigid_fast", 3.0)
    assert cal.provenance["sweeps_total"] == 120 and cal.n == cal.provenance["sweeps_fitted"] >= 100
    assert cal.provenance["b_p_mm"] == 3.0 and cal.alpha_coef is not None and cal.a_p_deg == 3.0
    assert_close(rigid_fast_line(inputs_dir(), cal.provenance["dt_s"]).to_json(), cal.to_json())


def test_a_tilelink_calibration_sweep_simulated_again_equals_its_committed_records():
    """One of the 72 calibration sweeps (31 probes, under a second) simulated live equals the committed cache's
    records: flags exactly, numbers within the cross-CPU tolerance (the last bits of a probe depend on the CPU,
    experiments/results/cross_cpu.md)."""
    from plate_env.build.eq10 import TILELINK, tilelink_specs
    from plate_env.run.sweeps import backend_tag, load_cache, run_cached, spec_key

    committed = load_cache(CACHE / SIMULATED[0])
    specs = tilelink_specs(3.0)[5 * 31:6 * 31]
    live = run_cached(TILELINK, specs, None, progress=False)
    tag = backend_tag(TILELINK)
    for s, r in zip(specs, live, strict=True):
        rec = committed[spec_key(tag, s)]
        assert_close([r.omega_b_deg_s, r.stderr_deg_s, r.unstable],
                     [rec["omega_b_deg_s"], rec["stderr_deg_s"], rec["unstable"]])


def test_build_calibration_eq10_refuses_incomplete_lab_sweeps_before_any_probe(tmp_path, capsys):
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "eval_tilelink_rigid_limit_A3_s100.jsonl").write_bytes((CACHE / "eval_tilelink_rigid_limit_A3_s100.jsonl")
                                                                   .read_bytes())
    argv, out = _eq10(tmp_path, tmp_path / "sweeps", lab)
    assert main(["build", *argv]) == 2
    err = capsys.readouterr().err
    assert "eval_pybullet_pybullet_A3_s600.jsonl lacks 216" in err and "does not simulate" in err
    assert not out.exists() and not (tmp_path / "sweeps").exists()
    # the lab families complete, the faithful line's sweeps missing: refused too, naming them
    (lab / "eval_pybullet_pybullet_A3_s600.jsonl").write_bytes((CACHE / "eval_pybullet_pybullet_A3_s600.jsonl")
                                                                .read_bytes())
    assert main(["build", *argv]) == 2
    err = capsys.readouterr().err
    assert "atlas_faithful.jsonl lacks 3720" in err and "does not simulate" in err
    assert not out.exists() and not (tmp_path / "sweeps").exists()
    # without --lab-sweeps the builder reads the sweeps frozen in the package: complete
    from plate_env.build.eq10 import LAB_SETS, LAB_SIMULATED, missing_lab_probes
    from plate_env.build.provenance import inputs_dir

    assert {f: missing_lab_probes(f, inputs_dir()) for f in LAB_SETS if f not in LAB_SIMULATED} == {
        "rigid": 0, "pybullet": 0}
    assert main(["build", "calibration", "paper", "--lab-sweeps", str(lab), "--out", str(out)]) == 2
    assert "eq10's options" in capsys.readouterr().err and not out.exists()


@pytest.mark.slow
def test_build_calibration_eq10_simulating_its_sweeps_equals_the_committed_ones(tmp_path):
    """The tile-link sweeps and the lab line's point-mass set simulated into an empty cache (5,952 probes, about 2
    minutes here): the same file as from the committed sweeps, and the same records."""
    argv, out = _eq10(tmp_path, tmp_path / "sweeps")
    assert main(["build", *argv]) == 0
    study = json.loads((ROOT / "experiments" / "results" / "eq10_rebuild.json").read_text())
    built = json.loads(out.read_text())
    assert {k: v for k, v in built.items() if k != RIGID} == study["rebuilt"]
    assert built[RIGID] == json.loads(_shipped("calibration.json"))[RIGID]
    from plate_env.run.sweeps import load_cache

    for name in SIMULATED:
        live, committed = load_cache(tmp_path / "sweeps" / name), load_cache(CACHE / name)
        assert live.keys() == committed.keys()
        assert all({**live[k], "wall_s": 0} == {**committed[k], "wall_s": 0} for k in live)
