"""What names a benchmark record (plate_env.bench.fingerprint): the code an episode runs, found from the imports of
the env, the episode loop and the backend, so no hand-kept list of file names goes stale."""

from __future__ import annotations

from plate_env.bench.fingerprint import code_fingerprint, outcome_modules, source_fingerprint


def test_the_outcome_modules_follow_the_imports_of_the_env_and_the_backend():
    atlas, tilelink = set(outcome_modules("atlas")), set(outcome_modules("tilelink"))
    for m in ("plate_env.env.rotation", "plate_env.env.codec", "plate_env.identify.inference",
              "plate_env.identify.calibration", "plate_env.surrogate.conditioning", "plate_env.core.probe"):
        assert m in atlas and m in tilelink
    assert "plate_env.physics.atlas_physics" in atlas and "plate_env.physics.atlas_physics" not in tilelink
    assert {"plate_env.physics.tilelink.kernels", "plate_env.physics.tilelink.rigid_kernels"} <= tilelink
    assert not any(m.startswith("plate_env.physics.tilelink") for m in atlas)
    assert "plate_env.physics.pybullet_sheet.scene" in set(outcome_modules("pybullet"))
    for not_outcome in ("plate_env.bench", "plate_env.run", "plate_env.build", "plate_env.cli", "plate_env.plotting",
                        "plate_env.env.sb3", "plate_env.env.vector", "plate_env_agents"):
        assert not any(m == not_outcome or m.startswith(not_outcome + ".") for m in atlas | tilelink), not_outcome


def test_the_fingerprint_ignores_docstrings_and_sees_code(tmp_path):
    a, b, c = tmp_path / "a.py", tmp_path / "b.py", tmp_path / "c.py"
    a.write_text('"""One."""\n\ndef f(x):\n    """Twice."""\n    return 2 * x\n')
    b.write_text('"""Another text."""\n\ndef f(x):\n    """Doubled."""\n    return 2 * x\n')
    c.write_text('"""One."""\n\ndef f(x):\n    """Twice."""\n    return 3 * x\n')
    assert source_fingerprint(a) == source_fingerprint(b) != source_fingerprint(c)
    assert code_fingerprint("atlas") != code_fingerprint("tilelink") and len(code_fingerprint("atlas")) == 64
