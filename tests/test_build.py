"""``plate-env build``: a shipped artifact rebuilt from the installed package equals the committed one, and records
its command, version and commit."""

from __future__ import annotations

import dataclasses
import json
import os
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from cross_cpu import assert_close

from plate_env.bench.suites import PINNED, content_hash, suite_dir, suite_names
from plate_env.cli import main
from plate_env.surrogate.atlas import Atlas, load_atlas_file


def _record_ok(record: dict, argv: list[str]) -> None:
    from plate_env.identify.lab_calibration_file import package_version

    assert record["command"] == "plate-env build " + " ".join(argv)
    assert record["plate_env"] == package_version() != "unknown"
    commit = record["commit"]  # a git checkout here (an installed wheel records None)
    assert commit is None or (len(commit.removesuffix("+dirty")) == 40 and int(commit[:40], 16) >= 0)


@pytest.mark.parametrize("name", suite_names())
def test_build_suite_writes_the_shipped_suite_byte_for_byte(name, tmp_path):
    out = tmp_path / f"{name}.json"
    argv = ["suite", name, "--out", str(out)]
    assert main(["build", *argv]) == 0
    assert out.read_bytes() == (suite_dir() / f"{name}.json").read_bytes()
    record = json.loads(Path(f"{out}.provenance.json").read_text())
    _record_ok(record, argv)
    assert record["sha256"] == content_hash(json.loads(out.read_text())) == PINNED[name]


def test_build_suite_refuses_an_unknown_suite_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "x.json"
    assert main(["build", "suite", "tilelink-v9", "--out", str(out)]) == 2
    assert "tilelink-v9" in capsys.readouterr().err and not out.exists()
    assert not Path(f"{out}.provenance.json").exists()


#: A slice of the shipped point-mass atlas (grid plate_env/data/grids/pointmass_m13.6.json, 4 repeats, seed 0):
#: 12 nodes, 48 probes (seconds), every node with a stable repeat, one with a single stable repeat.
SLICE = ["--select", "f_p_hz=10,25", "--select", "a_p_deg=3", "--select", "omega_n_pi=1.4,5.0277,45",
         "--select", "alpha_deg=26,48.8"]


def test_build_atlas_rebuilds_nodes_of_the_shipped_atlas_bit_for_bit(tmp_path):
    shipped = load_atlas_file("atlas_tilelink_pointmass.npz")
    prov = shipped.provenance
    assert (prov["repeats"], prov["seed"], Path(prov["grid"]).stem) == (4, 0, "pointmass_m13.6")
    out = tmp_path / "slice.npz"
    argv = ["atlas", "--grid", "pointmass_m13.6", "--repeats", "4", "--seed", "0", "--held-out", "0", *SLICE,
            "--out", str(out), "--cache-dir", str(tmp_path)]
    assert main(["build", *argv]) == 0
    built = Atlas.load(out)
    _record_ok(built.provenance["built_by"], argv)
    # the machine, which decides the last bits a rebuild elsewhere may not repeat (experiments/results/atlas_rebuild.md)
    from llvmlite import binding as ll

    ll.initialize_native_target()
    host = built.provenance["machine"]
    assert host["numba_cpu"] == (os.environ.get("NUMBA_CPU_NAME") or ll.get_host_cpu_name()) != ""
    assert host["blas"] and all(b.split()[0] in ("openblas", "mkl", "blis") for b in host["blas"])
    ix = np.ix_([list(shipped.f_hz).index(f) for f in built.f_hz], [list(shipped.a_p_deg).index(a) for a in
                built.a_p_deg], [int(np.argmin(abs(shipped.omega_n - w))) for w in built.omega_n],
                [int(np.argmin(abs(shipped.alpha - a))) for a in built.alpha])
    assert np.allclose(shipped.omega_n[ix[2].ravel()], built.omega_n, rtol=1e-12)
    n_stable = np.rint((1 - built.p_unstable) * 4)
    assert built.mean.shape == (2, 1, 3, 2) and n_stable.min() >= 1 and (n_stable == 1).sum() == 1
    # as stored (float32): the instability share and the mean of every node, the spread of every node with two
    # or more stable repeats. A node with one stable repeat gets at least the median spread over the whole grid's
    # nodes (atlas_from_repeats), which a slice cannot know: not compared.
    for key in ("p_unstable", "mean"):
        assert np.array_equal(getattr(shipped, key)[ix], getattr(built, key).astype(np.float32).astype(float)), key
    multi = n_stable >= 2
    assert np.array_equal(shipped.spread[ix][multi], built.spread.astype(np.float32).astype(float)[multi])


def test_the_faithful_atlas_rebuilds_from_its_committed_cache_without_a_live_probe(tmp_path, monkeypatch):
    """The shipped rigid-tile atlas (grid ``faithful``) is its committed probe cache reduced: rebuilt from a copy of
    that cache by the command its report names, no probe is simulated (any would have to start an executor) and the
    atlas equals the shipped one (numbers within CROSS_CPU_RTOL, the grid exactly)."""
    import shutil

    from plate_env.run import sweeps

    cache = ROOT / "experiments" / "cache"
    for name in ("atlas_faithful.jsonl", "atlas_heldout_faithful.jsonl"):
        shutil.copy(cache / name, tmp_path / name)

    def no_live_probe(*args, **kwargs):
        raise AssertionError("a probe missing from the committed cache would be simulated")

    monkeypatch.setattr(sweeps, "make_executor", no_live_probe)
    out = tmp_path / "faithful.npz"
    argv = ["atlas", "--physics", "tilelink", "--model", "rigid_fast", "--grid", "faithful", "--repeats", "2",
            "--seed", "0", "--executor", "pool:2", "--name", "faithful", "--cache-dir", str(tmp_path),
            "--out", str(out)]
    assert main(["build", *argv]) == 0
    shipped, built = load_atlas_file("atlas_tilelink_rigid_fast.npz"), Atlas.load(out)
    _record_ok(built.provenance["built_by"], argv)
    assert tuple(shipped.a_p_deg) == (3.0, 6.0) and np.array_equal(np.diff(shipped.f_hz), np.ones(30))
    assert shipped.omega_n.size >= 16 and shipped.alpha.size >= 5 and shipped.provenance["repeats"] == 2
    for key in ("f_hz", "a_p_deg", "omega_n", "alpha"):
        assert np.array_equal(getattr(shipped, key), getattr(built, key)), key
    for key in ("mean", "spread", "p_unstable"):
        assert_close(getattr(shipped, key).tolist(), getattr(built, key).astype(np.float32).astype(float).tolist())
    assert_close(shipped.provenance["sigma_model_deg_s"], built.provenance["sigma_model_deg_s"])


def test_build_atlas_refuses_a_value_off_the_grid_before_any_probe(tmp_path, capsys):
    out = tmp_path / "a.npz"
    assert main(["build", "atlas", "--grid", "pointmass_m13.6", "--select", "omega_n_pi=1.5", "--out", str(out),
                 "--cache-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "omega_n_pi = 1.5" in err and "not on the grid" in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


ROOT = Path(__file__).resolve().parents[1]


def test_build_forward_models_writes_the_shipped_registry(tmp_path):
    """The same registry as the shipped file: every key, member, text and layout exactly; the fitted numbers within
    the cross-CPU tolerance (they are recomputed from the results through fits whose last bits depend on the CPU)."""
    from plate_env.build.provenance import inputs_dir

    out = tmp_path / "fm.json"
    within, lomo = (inputs_dir() / f"forward_models_{s}.json" for s in ("within", "lomo"))
    faithful = inputs_dir() / "faithful_forward.json"
    argv = ["forward-models", "--out", str(out)]  # the inputs frozen in the package by default
    assert main(["build", *argv]) == 0
    shipped = (resources.files("plate_env") / "data" / "forward_models.json").read_text()
    assert_close(json.loads(out.read_text()), json.loads(shipped))
    assert out.read_text().count("\n") == shipped.count("\n")  # the writer's layout
    record = json.loads(Path(f"{out}.provenance.json").read_text())
    _record_ok(record, argv)
    assert record["inputs"] == {"within": str(within), "lomo": str(lomo), "faithful": str(faithful)}
    # the fitted values come from the results: another within sigma_eps gives another registry
    changed = {**json.loads(within.read_text()), "sigma_eps": 0.5}
    (tmp_path / "w.json").write_text(json.dumps(changed))
    assert main(["build", "forward-models", "--within", str(tmp_path / "w.json"), "--lomo", str(lomo),
                 "--faithful", str(faithful), "--out", str(out)]) == 0
    assert json.loads(out.read_text())["tilelink/pointmass"]["sigma_eps"] == 0.5
    (tmp_path / "f.json").write_text(json.dumps({**json.loads(faithful.read_text()), "sigma_eps": 0.25}))
    assert main(["build", "forward-models", "--within", str(within), "--lomo", str(lomo),
                 "--faithful", str(tmp_path / "f.json"), "--out", str(out)]) == 0
    assert json.loads(out.read_text())["tilelink/rigid_fast"]["sigma_eps"] == 0.25


def test_build_forward_models_refuses_a_missing_result_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "fm.json"
    assert main(["build", "forward-models", "--within", str(tmp_path / "no.json"), "--lomo", "x.json",
                 "--faithful", "y.json", "--out", str(out)]) == 2
    assert "no.json" in capsys.readouterr().err and not out.exists()


def test_every_shipped_grid_file_is_package_data():
    grids = resources.files("plate_env") / "data" / "grids"
    assert {"pointmass_m13.6.json", "pybullet.json"} <= {p.name for p in grids.iterdir()}


def test_build_calibration_paper_equals_the_shipped_file_but_for_the_commit_it_records(tmp_path):
    """The paper calibration from the paper's numbers through the public calibration function: every field equal to
    the shipped file's but ``commit`` (the schema hashes the writer's commit into the body) within the cross-CPU
    tolerance, and on the machine that made the shipped file, with the shipped commit put back, the same bytes."""
    from plate_env.identify import lab_calibration_file as lcf

    out = tmp_path / "calibration_paper.json"
    argv = ["calibration", "paper", "--out", str(out)]
    assert main(["build", *argv]) == 0
    shipped_bytes = (resources.files("plate_env") / "data" / lcf.PAPER_FILE).read_bytes()
    shipped, built = json.loads(shipped_bytes), json.loads(out.read_text())
    assert shipped.keys() == built.keys()
    same = {k: built[k] for k in built if k not in ("commit", "content_sha256")}
    if assert_close(same, {k: shipped[k] for k in same}) == 0.0:  # bit-equal numbers: then the bytes are too
        # the built file's key order, its commit replaced by the shipped one (a dict update keeps the key's place)
        body = {k: shipped["commit"] if k == "commit" else v for k, v in built.items() if k != "content_sha256"}
        text = json.dumps({**body, "content_sha256": lcf.content_hash(body)}, indent=1) + "\n"
        assert text.encode() == shipped_bytes
    rebuilt, paper = lcf.load(out).posterior, lcf.load(lcf.PAPER).posterior  # the rebuilt file reads (its hash holds)
    assert_close(dataclasses.asdict(rebuilt), dataclasses.asdict(paper))
    record = json.loads(Path(f"{out}.provenance.json").read_text())
    _record_ok(record, argv)
    assert record["content_sha256"] == built["content_sha256"]


def test_build_calibration_refuses_an_unknown_name_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "c.json"
    assert main(["build", "calibration", "lab", "--out", str(out)]) == 2
    assert "'lab'" in capsys.readouterr().err and not out.exists()


def _shipped_design_discrepancy() -> bytes:
    return (resources.files("plate_env_agents") / "models" / "bayes_design_discrepancy.json").read_bytes()


def test_build_design_discrepancy_writes_the_shipped_file_byte_for_byte_and_bayes_reads_it(tmp_path):
    from plate_env.build.provenance import inputs_dir
    from plate_env_agents import bayes

    within = inputs_dir() / "forward_models_within.json"  # frozen in the package, the default input
    out = tmp_path / "d.json"
    argv = ["design-discrepancy", "--out", str(out)]
    assert main(["build", *argv]) == 0
    assert out.read_bytes() == _shipped_design_discrepancy()
    _record_ok(json.loads(Path(f"{out}.provenance.json").read_text()), argv)
    built = json.loads(out.read_text())["design_discrepancy"]
    assert bayes.DESIGN_DISCREPANCY == {k: (v["scale"], v["nu"]) for k, v in built.items()}
    fit = json.loads(within.read_text())["bayes"]
    assert bayes.DESIGN_DISCREPANCY["tilelink/pointmass"] == (round(fit["sigma_design_fit"], 4), fit["nu_design_fit"])
    # a fitted value lives in data, not in the agent's code (neither the value once pasted there nor today's)
    code = (ROOT / "agents" / "bayes.py").read_text()
    assert "0.0091" not in code and str(bayes.DESIGN_DISCREPANCY["tilelink/pointmass"][0]) not in code
    # another fit gives another file: the comparison above can fail
    numbers = json.loads(within.read_text())
    numbers["bayes"]["sigma_design_fit"] = 0.0123
    (tmp_path / "w.json").write_text(json.dumps(numbers))
    assert main(["build", "design-discrepancy", "--within", str(tmp_path / "w.json"), "--out", str(out)]) == 0
    assert out.read_bytes() != _shipped_design_discrepancy()


def test_build_design_discrepancy_refuses_results_without_the_fit_and_writes_nothing(tmp_path, capsys):
    (tmp_path / "w.json").write_text(json.dumps({"sigma_eps": 0.01}))
    out = tmp_path / "d.json"
    assert main(["build", "design-discrepancy", "--within", str(tmp_path / "w.json"), "--out", str(out)]) == 2
    assert "no bayes design fit" in capsys.readouterr().err and not out.exists()
