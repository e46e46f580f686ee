"""Bad input and faults (issue 16): each defect found by the audit of main as a test that failed there.

Refusals name the value and the allowed range before any work is done; nothing is clamped or ignored silently.
Fast: atlas physics, or tile-link runs that are refused before they start.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import plate_env as pe
from plate_env.core.probe import ProbeSpec
from plate_env.env.rotation import PlateRotationEnv
from plate_env.physics.interface import PhysicsBackend
from plate_env.surrogate.atlas import load_atlas

PROBE = np.array([0.0, -1.0, 0.0, -1.0], np.float32)


def spec(obj=None, f_p_hz=25.0, a_p_deg=3.0, b_p_mm=3.0, **kw) -> ProbeSpec:
    return ProbeSpec(obj or pe.preset("cheese"), pe.PlateMotion.from_paper(f_p_hz, a_p_deg, b_p_mm), **kw)


# ------------------------------------------------------------------------- defect 6: atlas physics off its grid
_ATLAS = load_atlas()
#: The shipped atlas's omega_n and alpha ranges as the refusal names them.
OMEGA_RANGE = f"{_ATLAS.omega_n[0] / math.pi:.4g}-{_ATLAS.omega_n[-1] / math.pi:.4g} pi rad/s"
ALPHA_RANGE = f"{math.degrees(_ATLAS.alpha[0]):.4g}-{math.degrees(_ATLAS.alpha[-1]):.4g} deg"


def _built_masses() -> str:
    """The masses of the shipped point-mass atlases along the mass axis, as the refusal names them."""
    from plate_env.surrogate.atlas import load_atlas_file
    from plate_env.surrogate.catalog import registry_member_atlases

    files = registry_member_atlases("tilelink/pointmass")[0]
    return str(sorted(float(round(load_atlas_file(f).fixed()["mass"] * 1e3, 2)) for f in files)) + " g"


MASSES = _built_masses()


@pytest.mark.parametrize("probe, names", [
    (spec(f_p_hz=200.0), ("f_p = 200 Hz", "10-40 Hz")),
    (spec(obj=pe.ObjectSpec(omega_n=1e-9)), ("omega_n", OMEGA_RANGE)),
    (spec(obj=pe.ObjectSpec(alpha=math.radians(10.0))), ("alpha = 10 deg", ALPHA_RANGE)),
    (spec(b_p_mm=0.0), ("B_p = 0 mm", "B_p = 3 mm")),
    (spec(b_p_mm=5.0), ("B_p = 5 mm", "B_p = 3 mm")),
    (spec(obj=pe.ObjectSpec(mass=0.05)), ("mass of 50 g", MASSES)),
    (spec(obj=pe.ObjectSpec(diameter=0.1)), ("diameter = 100 mm", "diameter = 80 mm")),
    (spec(a_p_deg=5.0), ("A_p = 5 deg", "3, 12 deg")),
])
def test_atlas_physics_refuses_probes_outside_its_atlas(probe, names):
    physics = pe.make_physics("atlas")
    good = spec()
    with pytest.raises(ValueError) as err:
        physics.run([good, probe])  # the whole call is refused, before any probe is answered
    for text in names:
        assert text in str(err.value)


def test_atlas_physics_answers_inside_and_flips_sign_with_b_p():
    physics = pe.make_physics("atlas")
    pos, neg = physics.run([spec(f_p_hz=24.0), spec(f_p_hz=24.0, b_p_mm=-3.0)])
    assert pos.omega_b_deg_s > 100 and neg.omega_b_deg_s < -100


def test_atlas_domain_follows_its_provenance():
    atlas = load_atlas("tilelink", "pointmass")
    assert atlas.fixed() == pytest.approx({"b_p": 0.003, "mass": 0.0136, "diameter": 0.08})  # shipped values
    heavy = type(atlas)(**{**{f: getattr(atlas, f) for f in ("physics", "model", "f_hz", "a_p_deg", "omega_n",
                                                                  "alpha", "mean", "spread", "p_unstable",
                                                                  "n_repeats")},
                              "provenance": {**atlas.provenance, "mass_g": 39.5, "b_p_mm": 2.0}})
    assert heavy.outside(mass=0.0395, b_p=-0.002) == {}
    assert set(heavy.outside(mass=0.0136, b_p=0.003)) == {"mass", "b_p"}
    assert set(atlas.outside(f_p_hz=10.0, omega_n=40 * math.pi, alpha=math.radians(28), a_p_deg=-12.0)) == set()


# ---------------------------------------------------------------- defects 6 and 8: env options and reset options
@pytest.mark.parametrize("kwargs, name", [
    (dict(camera_fps=0), "camera_fps"),
    (dict(camera_fps=float("nan")), "camera_fps"),
    (dict(camera_fps=-30), "camera_fps"),
    (dict(angle_noise_deg=-1), "angle_noise_deg"),
    (dict(cost_per_sim_s=float("nan")), "cost_per_sim_s"),
    (dict(error_cap=0.0), "error_cap"),
    (dict(no_estimate_penalty=float("inf")), "no_estimate_penalty"),
    (dict(amplitudes_deg=(5.0,)), "amplitudes_deg"),  # the atlas holds 3 and 12 deg only
    (dict(amplitudes_deg=(3.0, 3.0)), "amplitudes_deg"),
    (dict(amplitudes_deg=()), "amplitudes_deg"),
    (dict(b_p_mm=1e6), "b_p_mm"),
    (dict(b_p_mm=2.0), "b_p_mm"),  # the atlas was built at 3 mm
    (dict(settle_s=-1), "settle_s"),
    (dict(max_probes=True), "max_probes"),
    (dict(max_probes=2.0), "max_probes"),
    (dict(max_sim_s=float("nan")), "max_sim_s"),
    (dict(mass_variation=0.9), "mass_variation"),  # 1.4-26 g: below the lightest atlas (5 g)
    (dict(f_band_hz=(5.0, 40.0)), "f_band_hz"),
    (dict(omega_n_range_pi=(1.0, 33.0)), "omega_n_range_pi"),
    (dict(render_mode="human2"), "render_mode"),
    (dict(physics_options=3), "physics_options"),
    (dict(physics_options={"instability_rh": 0.9}), "physics_options"),  # misspelt: was a TypeError
    (dict(physics_options={"instability_rho": 1.5}), "physics_options"),
    (dict(physics="bullet"), "physics"),
    (dict(method="fit"), "method"),
    (dict(alpha_range_deg=(60.0, 30.0)), "alpha_range_deg"),
    (dict(measure_range_s=(0.5,)), "measure_range_s"),
    (dict(camera_fps=True), "camera_fps"),
    (dict(calibration=3), "calibration"),
    (dict(calibration="paper", amplitudes_deg=(12.0,)), "calibration"),  # the paper calibration is at 3 deg
    (dict(reveal_truth="yes"), "reveal_truth"),
])
def test_env_options_refused_at_construction_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        PlateRotationEnv(physics=kwargs.pop("physics", "atlas"), **kwargs)


def test_every_constructor_argument_has_a_refusal_case():
    """Each argument of PlateRotationEnv (the fields of its EnvConfig) is refused with a message naming it somewhere
    in the table above (a new argument without a check fails here)."""
    from plate_env.env.config import ARGUMENTS

    named = {name for _, name in test_env_options_refused_at_construction_naming_them.pytestmark[0].args[1]}
    assert len(ARGUMENTS) == 21 and set(ARGUMENTS) <= named, set(ARGUMENTS) - named


def test_max_probes_has_one_default_everywhere():
    from plate_env.bench.suites import load_suite
    from plate_env.cli import build_parser
    from plate_env.env.protocol import ProbeContext  # noqa: F401 - the agents read the env's budget through it
    from plate_env.env.rotation import DEFAULT_MAX_PROBES

    assert PlateRotationEnv(physics="atlas").max_probes == DEFAULT_MAX_PROBES == 30
    args = build_parser().parse_args(["identify"])
    assert args.max_probes == DEFAULT_MAX_PROBES
    assert load_suite("tilelink-v0").env_kwargs["max_probes"] == DEFAULT_MAX_PROBES
    import json

    from plate_env_agents.ppo import DEFAULT_MODEL

    prov = json.loads(DEFAULT_MODEL.with_suffix(".json").read_text())
    assert prov["env_kwargs"]["max_probes"] == DEFAULT_MAX_PROBES  # the shipped policy's training budget


def test_env_options_the_live_physics_can_honour_are_accepted():
    env = PlateRotationEnv(physics="tilelink", mass_variation=0.2, b_p_mm=2.0, amplitudes_deg=(5.0,), max_probes=2)
    env.reset(seed=0)
    env.close()


@pytest.mark.parametrize("options, name", [
    ({"omega": 5.0}, "omega"),  # misspelt: was silently ignored (a random object instead)
    ({"omega_n": "10pi"}, "omega_n"),
    ({"alpha": float("nan")}, "alpha"),
    ({"mass": -1.0}, "mass"),
    ({"mass": 0.0025}, "mass"),  # atlas: built at 5-40 g
    ({"omega_n": 1e-9}, "omega_n"),  # atlas: off its grid
    ([("omega_n", 30.0)], "reset options"),
])
def test_reset_options_checked_naming_them(options, name):
    env = PlateRotationEnv(physics="atlas")
    with pytest.raises(ValueError, match=name):
        env.reset(seed=0, options=options)


def test_reset_options_fix_the_object_without_changing_the_seeded_draws():
    env = PlateRotationEnv(physics="atlas", max_probes=3)
    env.reset(seed=4, options={"omega_n": 30.0, "alpha": 0.7})
    assert (env.hidden_object().omega_n, env.hidden_object().alpha) == (30.0, 0.7)
    a = env.step(PROBE)[0]
    env.reset(seed=4, options={"omega_n": 30.0, "alpha": 0.7, "mass": 0.0136})
    assert np.array_equal(a, env.step(PROBE)[0])


@pytest.mark.parametrize("action", [
    np.array([0.0, -1.0, 0.0, -1.0], np.complex128),
    np.array([True, False, False, False]),
    [True, False, False, False],
    np.array(["0", "0", "0", "-1"]),
])
def test_complex_bool_and_text_actions_refused(action):
    env = PlateRotationEnv(physics="atlas")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="real numbers"):
        env.step(action)
    assert len(env.table()) == 0


def test_step_and_reset_after_close_raise():
    env = PlateRotationEnv(physics="atlas")
    env.reset(seed=0)
    env.step(PROBE)
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.step(PROBE)
    with pytest.raises(RuntimeError, match="closed"):
        env.reset(seed=1)


# ----------------------------------------------------------------------------------------------------- the CLI
def run_cli(argv, capsys) -> tuple[int, str, str]:
    from plate_env.cli import main

    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse refuses a value while parsing: exit 2 with its usage line
        code = exc.code if isinstance(exc.code, int) else 2
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


@pytest.mark.parametrize("argv, names", [
    (["identify", "--physics", "atlas", "--omega-n", "17pi", "--seed", "-1"], ("--seed", "[0,")),  # defect 1
    (["identify", "--physics", "atlas", "--seed", "1.5"], ("--seed", "integer")),
    (["sweep", "--physics", "atlas", "--omega-n", "10pi", "--freqs", "1:200:1e-12"], ("--freqs", "1.99e+14 probes")),
    (["sweep", "--physics", "atlas", "--omega-n", "10pi", "--freqs", "1:200:1e-5"], ("--freqs", "1.99e+07 probes")),
    (["identify", "--physics", "atlas", "--target", "nan"], ("--target", "(0, 1)")),  # defect 9
    (["identify", "--physics", "atlas", "--target", "-1"], ("--target", "(0, 1)")),
    (["identify", "--physics", "atlas", "--target", "inf"], ("--target", "(0, 1)")),
    (["identify", "--physics", "atlas", "--agent", "grid", "--target", "0.1"], ("--target", "bayes")),
    (["identify", "--physics", "atlas", "--omega-n", "-10pi"], ("--omega-n", "positive")),
    (["probe", "--physics", "atlas", "--freq", "25", "--alpha", "-5"], ("--alpha", "(0, 90)")),
    (["probe", "--physics", "atlas", "--freq", "25", "--measure", "-inf"], ("--measure", "(0, 600]")),
    (["probe", "--freq", "25", "--dt", "1e-9"], ("dt = 1e-09 s", "time steps")),  # defect 5: refused, not hours
    (["sweep", "--freqs", "10:40:1", "--dt", "1e-9"], ("dt = 1e-09 s", "time steps")),
    (["identify", "--agent", "grid", "--dt", "1e-9"], ("dt", "time steps")),
])
def test_cli_refuses_bad_values_naming_the_option(argv, names, capsys):
    code, out, err = run_cli(argv, capsys)
    assert code == 2 and out == ""
    for name in names:
        assert name in err


def test_cli_warns_when_dt_is_above_the_measured_stability_limit(capsys):
    code, out, err = run_cli(["probe", "--freq", "25", "--dt", "1e-3"], capsys)  # defect 5
    assert code == 0 and "UNSTABLE" in out
    assert "warning: dt = 0.001 s is above the largest time step measured stable" in err
    assert "0.0004 s" in err and "stress_tilelink_pointmass.md" in err
    with pytest.warns(UserWarning, match="dt = 0.0003 s is above .* rigid model"):
        pe.make_physics("tilelink", model="rigid", dt=3e-4)


class Interrupting(PhysicsBackend):
    """Wraps a backend and raises KeyboardInterrupt (Ctrl-C) in its ``interrupt_at``-th run call."""

    def __init__(self, inner, interrupt_at: int) -> None:
        self.inner, self.name, self.interrupt_at, self.calls = inner, inner.name, interrupt_at, 0

    def run(self, probes, progress=False):
        self.calls += 1
        if self.calls == self.interrupt_at:
            raise KeyboardInterrupt
        return self.inner.run(probes)

    def close(self) -> None:
        self.inner.close()


@pytest.mark.parametrize("json_out", [False, True])
def test_cli_sweep_interrupted_prints_the_finished_probes(json_out, monkeypatch, capsys):
    import json

    import plate_env.cli.sweep as cli

    class OnPhysics:  # an in-process executor that runs every chunk on one built backend
        name = "inprocess"

        def __init__(self, physics) -> None:
            self.physics = physics

        def map(self, fn, items):
            for i, item in enumerate(items):
                yield i, self.physics.run(list(item))

        def close(self) -> None:
            self.physics.close()

    monkeypatch.setattr(cli, "make_executor", lambda name, backend: OnPhysics(Interrupting(backend.build(), 3)))
    argv = ["sweep", "--physics", "atlas", "--omega-n", "10pi", "--freqs", "10:40:0.5", "--no-progress"]
    code, out, err = run_cli(argv + (["--json"] if json_out else []), capsys)  # defect 2
    assert code == 130 and "interrupted after 16 of 61 probes" in err
    if json_out:
        doc = json.loads(out)
        assert doc["interrupted"] is True
        assert [p["f_p_hz"] for p in doc["probes"]] == [10.0 + 0.5 * k for k in range(16)]
    else:
        rows = [ln for ln in out.splitlines() if ln.strip().endswith("stable") or "unstable:" in ln]  # any state
        assert len(rows) == 16 and rows[0].split()[0] == "10.00" and rows[-1].split()[0] == "17.50"


@pytest.mark.parametrize("argv", [
    ["sweep", "--physics", "atlas", "--freqs", "20,25"],
    ["identify", "--physics", "atlas", "--agent", "grid", "--max-probes", "3"],
    ["fit", "LAB"],
])
@pytest.mark.parametrize("plot, message", [
    ("/nonexistent/x.png", "does not exist"),
    ("DIR", "is a directory"),
    ("x.bogus", "unknown image format"),
])
def test_cli_plot_path_checked_before_any_work(argv, plot, message, tmp_path, monkeypatch, capsys):
    import plate_env.cli.probe as cli

    lab = tmp_path / "lab.csv"
    lab.write_text("f_p_hz,omega_b_deg_s\n" + "".join(f"{f},{300 + f}\n" for f in range(10, 30)))
    plot = {"DIR": str(tmp_path), "x.bogus": str(tmp_path / "x.bogus")}.get(plot, plot)

    def no_work(*a, **kw):
        raise AssertionError("work started before --plot was checked")

    monkeypatch.setattr(cli, "make_physics", no_work)
    monkeypatch.setattr("plate_env.run.executor.make_physics", no_work)
    monkeypatch.setattr("plate_env.identify.identify", no_work)
    monkeypatch.setattr("gymnasium.make", no_work)
    code, out, err = run_cli([str(lab) if a == "LAB" else a for a in argv] + ["--amp", "3"] * (argv[0] == "fit")
                             + ["--plot", plot], capsys)  # defect 3
    assert code == 2 and "--plot" in err and message in err and out == ""


@pytest.mark.parametrize("argv", [
    ["sweep", "--physics", "atlas", "--freqs", "20,25"],
    ["identify", "--physics", "atlas", "--agent", "grid", "--max-probes", "3"],
    ["fit", "LAB", "--amp", "3"],
])
def test_cli_prints_results_before_plotting_and_names_the_file_written(argv, tmp_path, monkeypatch, capsys):
    lab = tmp_path / "lab.csv"
    lab.write_text("f_p_hz,omega_b_deg_s\n" + "".join(f"{f},{600 / (1 + ((f - 25) / 5) ** 2)}\n"
                                                      for f in range(10, 40)))
    argv = [str(lab) if a == "LAB" else a for a in argv]
    code, out, _ = run_cli(argv + ["--plot", str(tmp_path / "somefile")], capsys)  # no extension: .png added
    assert code in (0, 1) and (tmp_path / "somefile.png").stat().st_size > 5000  # 1: no estimate from 3 probes
    assert out.rstrip().endswith(f"plot: {tmp_path / 'somefile.png'}")

    def broken(*a, **kw):
        raise OSError("disk full")

    monkeypatch.setattr("plate_env.plotting.plot_sweep", broken)
    monkeypatch.setattr("plate_env.plotting.plot_fit", broken)
    code, out, err = run_cli(argv + ["--plot", str(tmp_path / "again.png")], capsys)
    assert code == 2 and "disk full" in err
    assert ("omega_B" in out) or ("omega_n_hat" in out) or ("no estimate" in out)  # the results were printed


# -------------------------------------------------------------------------------- defect 10: a torn cache line
class Counting:
    """Wraps a backend and counts the probes it simulates."""

    def __init__(self, inner) -> None:
        self.inner, self.name, self.simulated = inner, inner.name, 0

    def __getattr__(self, name):  # model, dt: the same cache keys as the backend itself
        return getattr(self.inner, name)

    def run(self, probes, progress=False):
        self.simulated += len(probes)
        return self.inner.run(probes)

    def close(self) -> None:
        self.inner.close()


def test_cached_sweep_after_a_torn_last_line_keeps_every_record_valid(tmp_path):
    import json

    from plate_env.run.sweeps import load_cache, run_cached

    specs = [spec(f_p_hz=float(f)) for f in range(10, 20)]
    cache = tmp_path / "sweep.jsonl"
    run_cached(pe.make_physics("atlas"), specs[:5], cache, chunk=5, progress=False)
    cache.write_text(cache.read_text()[:-40])  # killed mid-write: the 5th record torn
    second = Counting(pe.make_physics("atlas"))
    resumed = run_cached(second, specs, cache, chunk=3, progress=False)
    assert second.simulated == 6  # the torn record and the 5 new ones
    lines = cache.read_text().splitlines()
    assert len(lines) == 10 and all(json.loads(line)["key"] for line in lines)
    third = Counting(pe.make_physics("atlas"))
    assert [r.omega_b_deg_s for r in run_cached(third, specs, cache, progress=False)] == [
        r.omega_b_deg_s for r in resumed]
    assert third.simulated == 0 and len(load_cache(cache)) == 10  # nothing recomputed on a rerun


# ----------------------------------------------------------------------------------------------- defect 7: CSV
def lab_rows(amps=(3.0,), f=range(12, 36)) -> str:
    return "".join(f"{x},{600 / (1 + ((x - 25) / 5) ** 2):.3f},{a:g}\n" for a in amps for x in f)


def test_csv_with_a_utf8_byte_order_mark_is_read(tmp_path):
    from plate_env.core.probe_table import read_lab_csv

    path = tmp_path / "excel.csv"
    path.write_bytes(("f_p_hz,omega_b_deg_s,a_p_deg\r\n" + lab_rows()).encode("utf-8-sig"))  # Excel "CSV UTF-8"
    table = read_lab_csv(path)
    assert len(table) == 24 and table.amplitudes() == [3.0]


@pytest.mark.parametrize("cell", ["-3", "0", "0.0", "46"])
def test_csv_amplitude_outside_0_45_refused_naming_line_and_column(cell, tmp_path):
    from plate_env.core.probe_table import CsvError, read_lab_csv

    path = tmp_path / "lab.csv"
    path.write_text(f"f_p_hz,omega_b_deg_s,a_p_deg\n20,300,3\n21,310,{cell}\n")
    with pytest.raises(CsvError, match="line 3, column a_p_deg.*outside the allowed range \\(0, 45\\]"):
        read_lab_csv(path)


def test_fit_amp_option_must_be_a_positive_magnitude(tmp_path, capsys):
    path = tmp_path / "lab.csv"
    path.write_text("f_p_hz,omega_b_deg_s\n" + "".join(f"{x},{x}\n" for x in range(10, 30)))
    code, _, err = run_cli(["fit", str(path), "--amp", "-3"], capsys)
    assert code == 2 and "--amp" in err and "(0, 45]" in err


def test_csv_duplicated_column_refused_naming_it(tmp_path):
    from plate_env.core.probe_table import CsvError, read_lab_csv

    path = tmp_path / "lab.csv"
    path.write_text("f_p_hz,omega_b_deg_s,f_p_hz\n20,300,20\n")
    with pytest.raises(CsvError, match="line 1: column\\(s\\) \\['f_p_hz'\\] appear more than once"):
        read_lab_csv(path, a_p_deg=3.0)


def test_mixed_amplitudes_without_a_calibration_are_not_dropped_silently(tmp_path, capsys):
    from plate_env.core.probe_table import read_lab_csv
    from plate_env.identify import identify

    path = tmp_path / "lab.csv"
    path.write_text("f_p_hz,omega_b_deg_s,a_p_deg\n" + lab_rows(amps=(3.0, 7.0)))
    est = identify(read_lab_csv(path), method="lorentz")
    assert not est.ok and "A_p = 7 deg" in est.reason and "no calibration" in est.reason
    code, out, _ = run_cli(["fit", str(path)], capsys)
    assert code == 1 and "no estimate: A_p = 7 deg" in out
    from plate_env.identify.lorentz import identify_lorentz

    # the calibrated amplitude alone does give an estimate (the Eq. (9)/(10) reading itself: a made-up Lorentzian
    # is no tile-link sweep, so identify's tile-link check would refuse it for another reason)
    alone = identify_lorentz(read_lab_csv(path).subset(np.isclose(read_lab_csv(path).a_p_deg, 3.0)))
    assert alone.ok


def test_negative_plate_amplitude_probes_identify_like_positive_ones():
    from plate_env.core.probe_table import ProbeTable
    from plate_env.identify import identify

    physics = pe.make_physics("atlas")
    freqs = np.arange(12.0, 36.0, 1.0)
    pos = physics.run([spec(f_p_hz=f) for f in freqs])
    neg = physics.run([spec(f_p_hz=f, a_p_deg=-3.0) for f in freqs])
    assert ProbeTable.from_results(neg).amplitudes() == [3.0]
    a, b = identify(pos, method="lorentz"), identify(neg, method="lorentz")
    assert a.ok and b.ok and b.omega_n == pytest.approx(a.omega_n, rel=0.2)


def test_cli_identify_interrupted_with_json_prints_the_finished_probes(monkeypatch, capsys):
    import json

    import plate_env.env.config as env_module  # where the env builds its backend

    real = env_module.make_physics
    monkeypatch.setattr(env_module, "make_physics", lambda name, **kw: Interrupting(real(name, **kw), 4))
    code, out, err = run_cli(["identify", "--physics", "atlas", "--agent", "grid", "--max-probes", "8", "--json"],
                             capsys)
    assert code == 130 and "interrupted after 3 probes" in err
    doc = json.loads(out)
    assert doc["interrupted"] is True and len(doc["probes"]) == 3 and doc["probes"][0]["f_p_hz"] == 10.0


@pytest.mark.slow
def test_ctrl_c_during_a_live_sweep_prints_the_finished_probes():
    """The real thing: SIGINT to ``plate-env sweep`` once its progress bar shows a finished chunk (defect 2)."""
    import re
    import signal
    import subprocess
    import sys
    import threading
    import time
    from pathlib import Path

    argv = [sys.executable, "-m", "plate_env", "sweep", "--omega-n", "10pi", "--freqs", "10:40:0.5", "--measure", "40"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parents[1],  # so Ctrl-C is not ignored as in a background job:
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(lambda: proc.stderr.read(1), "")), daemon=True)
    reader.start()
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and not re.search(r"\b([1-9]\d*)/61\b", "".join(err)):
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    out = proc.stdout.read()
    assert proc.wait(timeout=600) == 130
    reader.join(timeout=10)
    done = int(re.search(r"interrupted after (\d+) of 61 probes", "".join(err)).group(1))
    rows = [ln for ln in out.splitlines() if ln.strip().endswith("stable") or "unstable:" in ln]
    assert done >= 8 and len(rows) == done
