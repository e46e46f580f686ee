"""plate_env/data/MANIFEST.json against the shipped files: every file of plate_env/data and plate_env_agents/models
listed with its SHA-256, the command that made it (a ``plate-env build`` artifact or a script of this checkout),
the version, the commit and its inputs' hashes; the checker catches each kind of disagreement; the benchmark's
record keys do not depend on the manifest; no package default points into experiments/."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest

from plate_env.build.commands import ARTIFACTS
from plate_env.build.provenance import (
    ENTRY_FIELDS,
    check_manifest,
    file_sha256,
    load_manifest,
    manifest_path,
    shipped_files,
)

ROOT = Path(__file__).resolve().parents[1]
COMMIT = re.compile(r"^[0-9a-f]{40}(\+dirty)?$")


def test_every_shipped_file_is_listed_with_its_hash_command_version_commit_and_inputs():
    files = shipped_files()
    assert len(files) >= 40 and any(n.startswith("plate_env_agents/models/") for n in files)
    assert check_manifest(load_manifest(), files, ARTIFACTS, ROOT) == []


def test_entries_state_their_commit_or_say_unknown_with_a_reason():
    for name, e in load_manifest()["files"].items():
        assert list(e)[:len(ENTRY_FIELDS)] == list(ENTRY_FIELDS), name
        assert COMMIT.match(e["commit"]) or (e["commit"] == "unknown" and e.get("note")), name
        assert COMMIT.match(e.get("committed_in", e["commit"])), name
        # "by hand" is for specifications only (the atlas grids), never for a computed file
        assert not e["command"].startswith("by hand") or name.startswith("plate_env/data/grids/"), name


def _planted(tmp_path):
    data = tmp_path / "data"
    data.mkdir(exist_ok=True)
    (data / "a.json").write_text("{}")
    (data / "b.npz").write_bytes(b"xyz")
    files = {"plate_env/data/a.json": data / "a.json", "plate_env/data/b.npz": data / "b.npz"}
    entry = {"command": "plate-env build suite x --out a.json", "plate_env": "0.1.0", "commit": "unknown",
             "inputs": {}}
    manifest = {"files": {n: {"sha256": file_sha256(p), **entry} for n, p in files.items()}}
    return files, manifest


def test_the_checker_finds_each_kind_of_disagreement(tmp_path):
    files, manifest = _planted(tmp_path)
    assert check_manifest(manifest, files, ARTIFACTS, ROOT) == []
    (tmp_path / "data" / "b.npz").write_bytes(b"changed")
    assert check_manifest(manifest, files, ARTIFACTS, ROOT) == [
        f"plate_env/data/b.npz: sha256 {manifest['files']['plate_env/data/b.npz']['sha256'][:12]} listed, the "
        f"file's is {file_sha256(files['plate_env/data/b.npz'])[:12]}"]
    files, manifest = _planted(tmp_path)
    (tmp_path / "data" / "c.json").write_text("[]")
    extra = {**files, "plate_env/data/c.json": tmp_path / "data" / "c.json"}
    assert check_manifest(manifest, extra, ARTIFACTS, ROOT) == ["plate_env/data/c.json: not in the manifest"]
    assert check_manifest(manifest, {"plate_env/data/a.json": files["plate_env/data/a.json"]}, ARTIFACTS,
                          ROOT) == ["plate_env/data/b.npz: listed, not shipped"]
    for command, why in (("plate-env build nothing --out a", "no build artifact ['nothing']"),
                         ("python experiments/no_such_script.py", "no script experiments/no_such_script.py"),
                         ("make it", "neither plate-env build nor python SCRIPT")):
        bad = json.loads(json.dumps(manifest))
        bad["files"]["plate_env/data/a.json"]["command"] = command
        assert check_manifest(bad, files, ARTIFACTS, ROOT) == [f"plate_env/data/a.json: command {command!r}: {why}"]
    bad = json.loads(json.dumps(manifest))
    bad["files"]["plate_env/data/a.json"]["commit"] = ""
    assert check_manifest(bad, files, ARTIFACTS, ROOT) == ["plate_env/data/a.json: no commit"]
    bad = json.loads(json.dumps(manifest))
    bad["files"]["plate_env/data/a.json"]["inputs"] = {"x": {"path": "plate_env/data/b.npz", "sha256": "0" * 64}}
    assert check_manifest(bad, files, ARTIFACTS, ROOT) == [
        "plate_env/data/a.json: input x (plate_env/data/b.npz) differs from the hash recorded"]


def test_benchmark_record_keys_do_not_depend_on_the_manifest():
    from plate_env.bench.fingerprint import code_fingerprint

    path = manifest_path()
    before = path.read_bytes()
    code_fingerprint.cache_clear()
    key = code_fingerprint("atlas")
    try:
        path.write_bytes(before.replace(b'"files"', b'"x": 1, "files"', 1))
        code_fingerprint.cache_clear()
        assert code_fingerprint("atlas") == key
    finally:
        path.write_bytes(before)
        code_fingerprint.cache_clear()


def _defaults(tree: ast.AST):
    """Every default value in a module: function parameters' and argparse ``default=``."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield from (d for d in (*node.args.defaults, *node.args.kw_defaults) if d is not None)
        elif isinstance(node, ast.Call):
            yield from (k.value for k in node.keywords if k.arg == "default")


def test_no_package_default_points_into_experiments():
    bad = []
    for path in sorted((ROOT / "plate_env").rglob("*.py")):
        for value in _defaults(ast.parse(path.read_text())):
            text = ast.unparse(value)
            if "experiments" in text:
                bad.append(f"{path.relative_to(ROOT)}:{value.lineno} {text}")
    assert bad == []


@pytest.mark.parametrize("name", ["forward_models_within.json", "forward_models_lomo.json", "faithful_forward.json",
                                  "eval_tilelink_rigid_limit_A3_s100.jsonl", "eval_pybullet_pybullet_A3_s600.jsonl"])
def test_the_builders_inputs_are_frozen_in_the_package_with_their_command(name):
    entry = load_manifest()["files"][f"plate_env/data/inputs/{name}"]
    assert entry["command"].startswith("python experiments/") and entry["note"].startswith("frozen copy of")


def test_a_build_outside_the_shipped_folders_leaves_the_manifest_alone(tmp_path):
    from plate_env.build.provenance import build_record, manifest_name, record_in_manifest

    before = manifest_path().read_bytes()
    out = tmp_path / "forward_models.json"
    out.write_text("{}")
    assert manifest_name(out) is None and not record_in_manifest(out, build_record(["forward-models"]))
    assert manifest_path().read_bytes() == before
    assert manifest_name(manifest_path().parent / "forward_models.json") == "plate_env/data/forward_models.json"


def test_the_atlas_file_cache_holds_every_shipped_atlas():
    """A fit of data of unknown origin reads every shipped atlas (the lab pool, each physics with its extensions):
    a cache smaller than the shipped set would reload atlases on every fit."""
    from plate_env.surrogate.atlas import load_atlas_file

    shipped = list((ROOT / "plate_env" / "data").glob("*.npz"))
    assert len(shipped) > 30 and load_atlas_file.cache_info().maxsize >= len(shipped)
