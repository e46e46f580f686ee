"""The evaluation suites' builder: ``plate-env build suite NAME --out FILE`` writes the suite ``NAME`` exactly as it
ships in ``plate_env/data/suites/NAME.json`` (objects drawn from the env's prior,
:class:`plate_env.core.objects.ObjectPrior`, with a fixed seed; rounded to the digits the files keep).

A suite file's content is pinned by its hash (:data:`plate_env.bench.suites.PINNED`), so the build record (command,
version, commit) goes to a file beside it, ``FILE.provenance.json``, and the suite itself stays byte-identical to
the shipped one. A new suite is a new entry of :func:`suites` under a new version, pinned after it is built.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from plate_env.bench.suites import content_hash
from plate_env.core.files import write_text_atomic
from plate_env.core.objects import ObjectPrior
from plate_env.core.setup import PAPER_SETUP
from plate_env.env.ids import FAITHFUL_IDS

#: Probe settings of the tile-link suites: the CLI's identify (and the shipped policy's training) settings.
TILELINK_ENV = {"method": "atlas", "f_band_hz": [10.0, 40.0], "amplitudes_deg": [3.0, 12.0],
                "measure_range_s": [0.25, 2.0], "settle_s": 0.5, "b_p_mm": 3.0, "max_probes": 30,
                "cost_per_sim_s": 0.005}
COST_MODEL = {"probe_s": "ramp 0.2 s + settle_s + the window; a probe that ends unstable costs the seconds it ran",
              "cost_per_sim_s": "the env's reward charges this per simulated second (scored here: error against "
                                "simulated probing seconds)"}


def objects(n: int, seed: int, seed_base: int, prior: ObjectPrior | None = None,
            mass_g: float = PAPER_SETUP.mass_g) -> list[dict]:
    """``n`` objects of ``prior`` drawn with ``seed`` (omega_n in pi rad/s to 4 decimals, alpha in degrees to 3),
    episode seeds ``seed_base``, ``seed_base + 1``, ..."""
    prior = prior or ObjectPrior()
    return [{"omega_n_pi": round(w / math.pi, 4), "alpha_deg": round(math.degrees(a), 3), "mass_g": mass_g,
             "seed": seed_base + i} for i, (w, a) in enumerate(prior.sample(n, seed))]


def suites() -> list[dict]:
    """Every suite this package ships, as the content of its file."""
    live = objects(100, seed=2014, seed_base=14_000)
    faithful = FAITHFUL_IDS["PlateRotationAtlas-v1"]
    return [
        {"name": "atlas-v0", "description": "Fast iteration: the tilelink-v0 objects and seeds with probes answered "
         "by the tile-link point-mass atlas (microseconds a probe).",
         "env_kwargs": {"physics": "atlas", **TILELINK_ENV}, "budgets_s": [10.0, 20.0, 40.0],
         "cost_model": COST_MODEL, "objects": live},
        {"name": "tilelink-v0", "description": "100 objects of the env's prior (omega_n log-uniform 3.5-33 pi rad/s, "
         "alpha 30-60 deg, the cheese slice's 13.6 g) on the paper's tile-link model (point mass), live.",
         "env_kwargs": {"physics": "tilelink", **TILELINK_ENV}, "budgets_s": [10.0, 20.0, 40.0],
         "cost_model": COST_MODEL, "objects": live},
        {"name": "pybullet-v0", "description": "A small live PyBullet suite: 6 objects inside the PyBullet atlas "
         "(6-30 pi rad/s), 3 deg probes at 10-26 Hz, the PyBullet atlas's settle time.",
         "env_kwargs": {"physics": "pybullet", "method": "atlas", "f_band_hz": [10.0, 26.0], "amplitudes_deg": [3.0],
                        "measure_range_s": [0.4, 1.0], "settle_s": 0.3, "b_p_mm": 3.0, "max_probes": 12,
                        "cost_per_sim_s": 0.005},
         "budgets_s": [4.0, 8.0, 12.0], "cost_model": COST_MODEL,
         "objects": objects(6, seed=3014, seed_base=15_000, prior=ObjectPrior((6.0, 30.0), (30.0, 60.0)))},
        {"name": "faithful-v0", "description": "The tilelink-v0 objects and seeds on the physics that reproduces the "
         "paper: probes answered by the rigid tile-link disc's 1 Hz atlas (rigid_fast, 3 and 6 deg; "
         "PlateRotationAtlas-v1), read through the forward model tilelink/rigid_fast.",
         "env_kwargs": {"physics": faithful["physics"], "physics_options": faithful["physics_options"],
                        **{**TILELINK_ENV, "amplitudes_deg": list(faithful["amplitudes_deg"])}},
         "budgets_s": [10.0, 20.0, 40.0], "cost_model": COST_MODEL, "objects": live},
        {"name": "rigid-v0", "description": "The first 24 tilelink-v0 (and faithful-v0) objects and seeds on the "
         "physics that reproduces the paper, live: the rigid tile-link disc (rigid_fast, 3 and 6 deg; "
         "PlateRotation-v1), about 1-2x real time a probe.",
         "env_kwargs": {"physics": FAITHFUL_IDS["PlateRotation-v1"]["physics"],
                        "physics_options": FAITHFUL_IDS["PlateRotation-v1"]["physics_options"],
                        **{**TILELINK_ENV, "amplitudes_deg": list(FAITHFUL_IDS["PlateRotation-v1"]["amplitudes_deg"])}},
         "budgets_s": [10.0, 20.0, 40.0], "cost_model": COST_MODEL, "objects": live[:24]},
        *misspec_suites(),
    ]


#: The misspecification track's episode physics: suite family -> (what answers the probes, the band it covers).
MISSPEC_PHYSICS = {
    "misspec_pointmass": ({"source": "tilelink", "model": "pointmass"}, [10.0, 40.0], "the tile-link point mass"),
    "misspec_faithful": ({"source": "tilelink", "model": "rigid_fast"}, [10.0, 40.0],
                         "the rigid tiles (rigid_fast, the physics that reproduces the paper)"),
    "misspec_pybullet": ({"source": "pybullet", "model": "pybullet"}, [10.0, 26.0],
                         "the PyBullet soft-body sheet (its atlas covers 10-26 Hz)"),
}


def misspec_suites() -> list[dict]:
    """The misspecification track (issue 33): the same 50 objects (omega_n log-uniform 6-30 pi rad/s, inside every
    shipped atlas; alpha 30-60 deg) and seeds on each episode physics of :data:`MISSPEC_PHYSICS`, at the one
    amplitude every forward model reads (3 deg), so that an agent whose estimate goes through another physics'
    forward model (``--agent NAME:forward=MODEL``) is scored on physics it was not built on."""
    prior = ObjectPrior((6.0, 30.0), (30.0, 60.0))
    shared = objects(50, seed=5014, seed_base=16_000, prior=prior)
    return [{"name": f"{family}-v0", "description": f"Misspecification track: 50 objects (6-30 pi rad/s) whose "
             f"probes are answered by {what}'s atlas, 3 deg, {band[0]:g}-{band[1]:g} Hz; the same objects and "
             "seeds as the track's other suites.",
             "env_kwargs": {"physics": "atlas", "physics_options": options,
                            **{**TILELINK_ENV, "amplitudes_deg": [3.0], "f_band_hz": band},
                            "omega_n_range_pi": list(prior.omega_n_range_pi), "alpha_range_deg": list(
                                prior.alpha_range_deg)},
             "budgets_s": [10.0, 20.0, 40.0], "cost_model": COST_MODEL, "objects": shared}
            for family, (options, band, what) in MISSPEC_PHYSICS.items()]


def suite_names() -> list[str]:
    """The names of the suites :func:`suites` builds."""
    return [s["name"] for s in suites()]


def suite_text(name: str) -> str:
    """The file text of suite ``name`` (the shipped files' format: JSON indented by one, a final newline).
    ValueError naming the known suites for another name."""
    for s in suites():
        if s["name"] == name:
            return json.dumps(s, indent=1) + "\n"
    raise ValueError(f"unknown suite {name!r}; this package builds {suite_names()}")


def build_suite(name: str, out: str | Path, record: dict) -> dict:
    """Write suite ``name`` to ``out`` and ``record`` (:func:`plate_env.build.provenance.build_record`) with the
    suite's content hash to ``out`` + ``.provenance.json``; returns that record. Nothing is written for an unknown
    name."""
    text = suite_text(name)
    out = Path(out)
    write_text_atomic(out, text, "--out")
    record = {**record, "artifact": "suite", "name": name, "sha256": content_hash(json.loads(text))}
    write_text_atomic(f"{out}.provenance.json", json.dumps(record, indent=1) + "\n", "build record")
    return record


__all__: Sequence[str] = ("MISSPEC_PHYSICS", "build_suite", "misspec_suites", "objects", "suite_names", "suite_text",
                          "suites")
