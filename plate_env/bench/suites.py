"""Named, versioned evaluation suites: fixed hidden objects with episode seeds, a probing budget and a cost model.

A suite is package data, ``plate_env/data/suites/<family>-v<N>.json``: the env's settings (physics and its options,
band, amplitudes, windows, probe budget, cost per simulated second), the probing budgets in simulated seconds at
which agents are scored (the largest ends every episode), and the objects, each with its omega_n (pi rad/s), alpha
(deg), mass (g) and the seed of its episode (the disc's placement and the camera noise, and the agent's generator).

Versioning: a suite's content is pinned by its SHA-256 (:data:`PINNED`, over the canonical JSON of the file). A
suite whose content no longer matches its pin is refused at load: changing a suite means saving it under a new
version (``tilelink-v1``) and pinning that, so a number reported on ``tilelink-v0`` always means the same episodes.
(The physics, forward models and agents a suite is run with are code; the benchmark's records name the code they
ran with, see :mod:`plate_env.bench.runner`.)
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from plate_env.core import checks
from plate_env.core.files import read_json
from plate_env.core.objects import ObjectSpec
from plate_env.core.setup import SEED_RANGE

if TYPE_CHECKING:
    from plate_env.env.rotation import PlateRotationEnv

#: The content hash of every shipped suite version. A new version is added here; an entry is never edited.
PINNED = {
    "atlas-v0": "acd39c7b32a3c4fc8340b60656b99dc8a1668f5ae64b9570e818608ea70586cc",
    "tilelink-v0": "71fd2838449a30527b2ada139ac8266d07567b45d2cf21968f70182ad44c96a8",
    "pybullet-v0": "b09609f8969e6227605b7f36796a2466f7b2e0b0d8a5b797c8fec7d6a6d38358",
    "faithful-v0": "a47b2db6c85e2f9070722158409477407e759e6d8a66dce0f53bd3a5b56bebac",
    "rigid-v0": "03d98d67f91e7cc97658225467298f0d65b731dbd4c053f3e21ab6a2f720371f",
    "misspec_pointmass-v0": "9307201c1ea16bf811be85225b7666f4ca45b157cf9c0a35d313394739f8a1b4",
    "misspec_faithful-v0": "c2c05d4da4e01b2be9949c83052d054b46d3ae037736cfb7709236d208419651",
    "misspec_pybullet-v0": "6491a7cc6827063808882b0be2ee63f2d1c77beb6e9b4902d2fe63d52cbc968d",
}
#: A suite's name: a family and a version.
NAME = re.compile(r"^(?P<family>[a-z][a-z0-9_]*)-v(?P<version>\d+)$")
#: Keys of a suite file.
KEYS = ("name", "description", "env_kwargs", "budgets_s", "cost_model", "objects")
#: Keys of one object.
OBJECT_KEYS = ("omega_n_pi", "alpha_deg", "mass_g", "seed")


@dataclass(frozen=True)
class SuiteObject:
    """One hidden object of a suite (SI) and the seed of its episode."""

    omega_n: float
    alpha: float
    mass: float
    seed: int

    def reset_options(self) -> dict:
        """The env's ``reset(options=...)`` that hides this object."""
        return {"omega_n": self.omega_n, "alpha": self.alpha, "mass": self.mass}


@dataclass(frozen=True)
class Suite:
    """A loaded suite (see the module docstring). ``env_kwargs`` are PlateRotation-v0's constructor arguments (the
    env's own budget ``max_sim_s`` is left unset: the benchmark enforces :attr:`max_budget_s` itself, so a policy
    sees the observation it was trained on); ``budgets_s`` ascending, simulated seconds; ``sha256`` the content
    hash."""

    name: str
    description: str
    env_kwargs: dict
    budgets_s: tuple[float, ...]
    cost_model: dict
    objects: tuple[SuiteObject, ...]
    sha256: str

    @property
    def max_budget_s(self) -> float:
        return self.budgets_s[-1]

    @property
    def physics(self) -> str:
        return self.env_kwargs["physics"]

    def make_env(self) -> PlateRotationEnv:
        """A fresh PlateRotation-v0 with the suite's settings."""
        from plate_env.env.rotation import PlateRotationEnv

        return PlateRotationEnv(**self.env_kwargs)


def content_hash(content: dict) -> str:
    """SHA-256 of a suite's canonical JSON (sorted keys, no spaces): formatting does not change it, content does."""
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def _tuple_values(kw: dict) -> dict:
    """JSON lists -> tuples for the env's pair and tuple arguments."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in kw.items()}


def parse_suite(content: dict, where: str = "suite") -> Suite:
    """A :class:`Suite` from a suite file's dict, checked (ValueError naming ``where`` and the key), not pinned."""
    if not isinstance(content, dict) or sorted(content) != sorted(KEYS):
        got = sorted(content) if isinstance(content, dict) else type(content).__name__
        raise ValueError(f"{where}: a suite has exactly the keys {sorted(KEYS)}, got {got}")
    name = content["name"]
    if not isinstance(name, str) or not NAME.match(name):
        raise ValueError(f"{where}: name {name!r} must be <family>-v<N>, e.g. tilelink-v0")
    budgets = content["budgets_s"]
    if (not isinstance(budgets, list) or not budgets or not all(isinstance(b, (int, float)) and 0 < b < 1e5
                                                                 for b in budgets)
            or sorted(set(budgets)) != budgets):
        raise ValueError(f"{where}: budgets_s {budgets!r} must be increasing positive simulated seconds")
    env_kwargs = _env_kwargs(content["env_kwargs"], where)
    objects = content["objects"]
    if not isinstance(objects, list) or not objects:
        raise ValueError(f"{where}: objects must be a list of at least one object, got {type(objects).__name__} "
                         f"{str(objects)[:40]!r}")
    if not isinstance(content["description"], str) or not isinstance(content["cost_model"], dict):
        raise ValueError(f"{where}: description must be a string and cost_model a dict, got "
                         f"{type(content['description']).__name__} and {type(content['cost_model']).__name__}")
    return Suite(name=name, description=content["description"], env_kwargs=_tuple_values(env_kwargs),
                 budgets_s=tuple(float(b) for b in budgets), cost_model=dict(content["cost_model"]),
                 objects=tuple(_object(o, f"{where}: objects[{i}]") for i, o in enumerate(objects)),
                 sha256=content_hash(content))


def _env_kwargs(kw: object, where: str) -> dict:
    """A suite's ``env_kwargs``: a dict naming the physics, with PlateRotation-v0's constructor arguments only
    (their values are the env's to check) and without ``max_sim_s`` (the budgets' job); ``physics_options`` a dict."""
    from plate_env.env.config import ARGUMENTS

    if not isinstance(kw, dict) or "physics" not in kw or "max_sim_s" in kw:
        raise ValueError(f"{where}: env_kwargs must name the physics and leave max_sim_s to budgets_s")
    allowed = [k for k in ARGUMENTS if k != "max_sim_s"]
    unknown = sorted(k for k in kw if k not in allowed)
    if unknown:
        raise ValueError(f"{where}: env_kwargs {unknown} are not PlateRotation-v0 arguments; allowed: {allowed}")
    if kw.get("physics_options") is not None and not isinstance(kw["physics_options"], dict):
        raise ValueError(f"{where}: env_kwargs physics_options = {kw['physics_options']!r} must be a dict")
    return kw


def _object(o: object, where: str) -> SuiteObject:
    """One object of a suite, its values checked: finite numbers inside :class:`ObjectSpec`'s ranges, a seed an
    integer in :data:`SEED_RANGE` (1.7 or "7" is refused, not rounded or converted)."""
    if not isinstance(o, dict) or sorted(o) != sorted(OBJECT_KEYS):
        raise ValueError(f"{where} must have exactly the keys {sorted(OBJECT_KEYS)}")
    try:
        omega_pi, alpha_deg, mass_g = (checks.real(k, o[k]) for k in OBJECT_KEYS[:3])
        seed = checks.integer("seed", o["seed"], *SEED_RANGE)
        obj = ObjectSpec(omega_n=math.pi * omega_pi, alpha=math.radians(alpha_deg), mass=mass_g * 1e-3)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return SuiteObject(omega_n=obj.omega_n, alpha=obj.alpha, mass=obj.mass, seed=seed)


def check_pinned(suite: Suite, pinned: dict[str, str] | None = None) -> Suite:
    """``suite`` if its content hash is the one pinned for its name, else ValueError saying what to do."""
    pins = PINNED if pinned is None else pinned
    if suite.name not in pins:
        raise ValueError(f"suite {suite.name!r} has no pinned content hash (known: {sorted(pins)}); a new suite "
                         f"version is pinned in plate_env.bench.suites.PINNED: {suite.sha256}")
    if pins[suite.name] != suite.sha256:
        raise ValueError(f"suite {suite.name!r}: its content changed (sha256 {suite.sha256[:12]}..., pinned "
                         f"{pins[suite.name][:12]}...): a changed suite is a new version; save it under the next "
                         "version and pin that one")
    return suite


def suite_dir() -> Path:
    from importlib import resources

    return Path(str(resources.files("plate_env") / "data" / "suites"))


def suite_names() -> list[str]:
    """The shipped suites."""
    return sorted(p.stem for p in suite_dir().glob("*.json"))


def load_suite_file(path: str | Path, pinned: dict[str, str] | None = None) -> Suite:
    """A suite from a JSON file (its stem must be its name), checked against its pin: a shipped suite's name always
    has one; a suite of your own under a new name loads unpinned (its hash is in every result)."""
    path = Path(path)
    content = read_json(path, "suite file", strict=True)
    suite = parse_suite(content, where=f"suite file {path.name}")
    if path.stem != suite.name:
        raise ValueError(f"suite file {path.name}: its name is {suite.name!r}; the file must be {suite.name}.json")
    pins = PINNED if pinned is None else pinned
    if suite.name not in pins and path.resolve().parent != suite_dir().resolve():
        return suite
    return check_pinned(suite, pins)


def load_suite(name: str) -> Suite:
    """A shipped suite by name (``atlas-v0``, ``tilelink-v0``, ``pybullet-v0``, ``faithful-v0``), or a suite file by
    path."""
    if name.endswith(".json"):
        return load_suite_file(name)
    path = suite_dir() / f"{name}.json"
    if not path.is_file():
        raise ValueError(f"unknown suite {name!r}; shipped: {suite_names()} (or give a suite .json file)")
    return load_suite_file(path)
