"""Versioned evaluation suites: shipped suites load and are pinned; an edit without a new version is refused."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from plate_env.bench.suites import (
    PINNED,
    content_hash,
    load_suite,
    load_suite_file,
    parse_suite,
    suite_dir,
    suite_names,
)

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_suites_load_and_every_one_is_pinned():
    assert suite_names() == sorted(PINNED) == ["atlas-v0", "faithful-v0", "misspec_faithful-v0",
                                               "misspec_pointmass-v0", "misspec_pybullet-v0", "pybullet-v0",
                                               "rigid-v0", "tilelink-v0"]
    for name in suite_names():
        s = load_suite(name)
        assert s.sha256 == PINNED[name] and s.name == name
        assert list(s.budgets_s) == sorted(s.budgets_s) and s.max_budget_s == s.budgets_s[-1]
        assert len({o.seed for o in s.objects}) == len(s.objects)  # one seed per episode
    live = load_suite("tilelink-v0")
    assert live.physics == "tilelink" and len(live.objects) >= 100 and live.budgets_s == (10.0, 20.0, 40.0)
    assert load_suite("atlas-v0").objects == live.objects  # fast iteration on the same episodes
    faithful = load_suite("faithful-v0")  # the same episodes on the rigid tiles' atlas (issue 33)
    assert faithful.objects == live.objects and faithful.physics == "atlas"
    assert faithful.env_kwargs["physics_options"] == {"model": "rigid_fast"}
    assert tuple(faithful.env_kwargs["amplitudes_deg"]) == (3.0, 6.0)
    rigid = load_suite("rigid-v0")  # the first 24 of them on the rigid tiles, live
    assert rigid.objects == live.objects[:24] and rigid.physics == "tilelink"
    assert rigid.env_kwargs["physics_options"] == {"model": "rigid_fast"}
    assert {k: v for k, v in rigid.env_kwargs.items() if k not in ("physics", "physics_options")} == {
        k: v for k, v in faithful.env_kwargs.items() if k not in ("physics", "physics_options")}
    lo, hi = (min(o.omega_n for o in live.objects) / math.pi, max(o.omega_n for o in live.objects) / math.pi)
    assert 3.5 <= lo and hi <= 33.0


def test_the_misspecification_suites_hold_the_same_episodes_on_three_physics_every_forward_model_reads():
    """Issue 33's track: one set of objects and seeds; the probes answered by the point mass's, the rigid tiles' and
    the PyBullet sheet's atlas; 3 deg only (the amplitude every forward model reads), inside every atlas's range."""
    from plate_env.identify.forward import load_forward_model

    suites = [load_suite(f"misspec_{p}-v0") for p in ("pointmass", "faithful", "pybullet")]
    assert suites[0].objects == suites[1].objects == suites[2].objects and len(suites[0].objects) == 50
    assert [s.env_kwargs["physics_options"]["model"] for s in suites] == ["pointmass", "rigid_fast", "pybullet"]
    for s in suites:
        assert s.physics == "atlas" and tuple(s.env_kwargs["amplitudes_deg"]) == (3.0,)
        env = s.make_env()  # the env refuses options its atlas cannot answer: every object is inside it
        for o in s.objects:
            assert 6.0 <= o.omega_n / math.pi <= 30.0
        env.close()
    for name in ("tilelink/pointmass", "tilelink/rigid_fast", "pybullet/pybullet", "lab"):
        assert all(3.0 in m.atlas.a_p_deg for m in load_forward_model(name).members)


def test_suite_envs_build_with_the_env_default_probe_budget():
    from plate_env.env.rotation import DEFAULT_MAX_PROBES

    for name in ("atlas-v0", "tilelink-v0"):
        env = load_suite(name).make_env()
        assert env.max_probes == DEFAULT_MAX_PROBES and env.max_sim_s is None
        env.close()


def _edited(tmp_path: Path, name: str, edit) -> Path:
    content = json.loads((suite_dir() / f"{name}.json").read_text())
    edit(content)
    path = tmp_path / f"{content['name']}.json"
    path.write_text(json.dumps(content))
    return path


def test_an_edited_suite_under_its_old_version_is_refused(tmp_path):
    def nudge(c):
        c["objects"][3]["alpha_deg"] += 0.001

    with pytest.raises(ValueError, match="new version"):
        load_suite_file(_edited(tmp_path, "tilelink-v0", nudge))
    with pytest.raises(ValueError, match="new version"):
        load_suite(str(_edited(tmp_path, "atlas-v0", lambda c: c["budgets_s"].append(80.0))))


def test_formatting_does_not_change_the_hash_and_a_new_name_loads_unpinned(tmp_path):
    same = _edited(tmp_path, "atlas-v0", lambda c: None)
    assert load_suite_file(same).sha256 == PINNED["atlas-v0"]  # json.dumps without indentation: same content

    def renamed(c):
        c["name"] = "mysuite-v0"
        c["objects"] = c["objects"][:2]

    s = load_suite_file(_edited(tmp_path, "atlas-v0", renamed))
    assert s.name == "mysuite-v0" and len(s.objects) == 2 and s.sha256 not in PINNED.values()


def test_content_hash_sees_every_field():
    c = json.loads((suite_dir() / "atlas-v0.json").read_text())
    base = content_hash(c)
    for path in (("objects", 0, "seed"), ("env_kwargs", "max_probes"), ("budgets_s", 0)):
        d = json.loads(json.dumps(c))
        node = d
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] += 1
        assert content_hash(d) != base, path


@pytest.mark.parametrize("edit, message", [
    (lambda c: c.pop("cost_model"), "exactly the keys"),
    (lambda c: c.update(name="tilelink"), "family"),
    (lambda c: c.update(budgets_s=[20.0, 10.0]), "budgets_s"),
    (lambda c: c["env_kwargs"].update(max_sim_s=5.0), "max_sim_s"),
    (lambda c: c["objects"][0].pop("seed"), r"objects\[0\]"),
    (lambda c: c.update(objects=[]), "at least one object"),
])
def test_malformed_suites_are_refused_naming_the_field(edit, message):
    c = json.loads((suite_dir() / "atlas-v0.json").read_text())
    edit(c)
    with pytest.raises(ValueError, match=message):
        parse_suite(c)


def test_unknown_suite_names_the_shipped_ones():
    with pytest.raises(ValueError, match="atlas-v0"):
        load_suite("tilelink-v9")


def test_suite_files_are_what_make_suites_writes():  # the checkout script over plate_env.build.suites
    done = subprocess.run([sys.executable, "experiments/make_suites.py", "--check"], cwd=ROOT, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stdout + done.stderr
