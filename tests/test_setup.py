"""One home for the paper's set-up and the allowed ranges (plate_env.core.setup): every default that means "the
paper's set-up" reads PAPER_SETUP, and every part of the package refuses the same masses, naming the range."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import pytest

from plate_env.build.atlas_grid import AtlasGrid
from plate_env.cli import build_parser, main
from plate_env.cli.fit import _fit_estimator
from plate_env.core.motion import PlateMotion
from plate_env.core.objects import PRESETS, ObjectSpec
from plate_env.core.setup import DIAMETER_RANGE_M, MASS_RANGE_KG, PAPER_SETUP
from plate_env.env.rotation import PlateRotationEnv
from plate_env.physics.tilelink.geometry import disc_geometry
from plate_env.surrogate.atlas import DEFAULT_BUILD
from plate_env.surrogate.conditioning import KnownInputs

ROOT = Path(__file__).resolve().parents[1]


def test_the_paper_setup_is_the_default_everywhere():
    assert (PAPER_SETUP.b_p, PAPER_SETUP.mass, PAPER_SETUP.diameter) == (0.003, 0.0136, 0.080)
    assert (PAPER_SETUP.b_p_mm, PAPER_SETUP.mass_g, PAPER_SETUP.diameter_mm) == (3.0, 13.6, 80.0)
    obj = ObjectSpec()
    assert (obj.mass, obj.diameter) == (PAPER_SETUP.mass, PAPER_SETUP.diameter)
    assert ObjectSpec.from_paper(10.0, 36.9) == ObjectSpec.from_paper(10.0, 36.9, 13.6, 80.0)
    assert PRESETS["cheese"].mass == pytest.approx(PAPER_SETUP.mass, rel=1e-15)
    assert PlateMotion(20.0, 0.05).b_p == PAPER_SETUP.b_p == PlateMotion.from_paper(20.0, 3.0).b_p
    assert KnownInputs() == KnownInputs(b_p=0.003, mass=0.0136, diameter=0.080)
    grid = AtlasGrid(omega_n_pi=(5.0, 10.0), alpha_deg=(30.0,), f_hz=(10.0, 20.0), a_p_deg=(3.0,))
    assert (grid.mass_g, grid.b_p_mm, grid.diameter_mm) == (13.6, 3.0, 80.0)
    assert DEFAULT_BUILD == {"b_p_mm": 3.0, "mass_g": 13.6, "diameter_mm": 80.0}
    assert disc_geometry().spacing == disc_geometry(PAPER_SETUP.diameter).spacing != disc_geometry(0.1).spacing
    env = PlateRotationEnv(physics="atlas")
    env.reset(seed=0)
    assert env.b_p_mm == 3.0 and env.known_inputs() == KnownInputs()
    env.close()
    for command in (["fit", "x.csv"], ["calibrate", "refs.csv", "--out", "cal.json"]):
        args = build_parser().parse_args(command)
        assert (args.bp, args.mass_g, args.diameter_mm) == (None, None, None)  # not given: filled in by the command
    fit = build_parser().parse_args(["fit", "x.csv"])
    assert _fit_estimator(fit).known == KnownInputs(b_p=0.003, mass=0.0136, diameter=0.080)  # args not changed
    assert (fit.bp, fit.mass_g, fit.diameter_mm) == (None, None, None)


def test_the_setup_numbers_are_written_once_in_the_library():
    """No float literal of the paper's mass (13.6 g, 0.0136 kg) or diameter (80 mm, 0.08 m) outside core/setup.py
    (docstrings are text and do not count)."""
    found = []
    for path in sorted((ROOT / "plate_env").rglob("*.py")):
        if path.name == "setup.py" and path.parent.name == "core":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and isinstance(node.value, float) and node.value in (
                    13.6, 0.0136, 80.0, 0.08):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.value}")
    assert found == []


@pytest.mark.parametrize("mass_kg", [MASS_RANGE_KG[0] * 0.99, MASS_RANGE_KG[1] * 1.01, 0.0, -0.01, math.nan])
def test_one_mass_range_refused_the_same_everywhere(mass_kg):
    with pytest.raises(ValueError, match=r"mass \(kg\) = .* outside the allowed range \[0.0001, 1\]"):
        ObjectSpec(mass=mass_kg)
    with pytest.raises(ValueError, match=r"mass = .* outside the allowed range \[0.0001, 1\]"):
        KnownInputs(mass=mass_kg)


def test_the_mass_range_holds_at_its_ends():
    for m in MASS_RANGE_KG:
        assert ObjectSpec(mass=m).mass == m and KnownInputs(mass=m).mass == m
    for d in DIAMETER_RANGE_M:
        assert ObjectSpec(diameter=d).diameter == d and KnownInputs(diameter=d).diameter == d
    with pytest.raises(ValueError, match=r"diameter \(m\) = 0.6 is outside the allowed range \[0.01, 0.5\]"):
        ObjectSpec(diameter=0.6)
    with pytest.raises(ValueError, match="mass"):
        ObjectSpec(mass=True)  # a bool is no mass


@pytest.mark.parametrize("argv", [["probe", "--freq", "20", "--amp", "3", "--mass-g", "1001"],
                                  ["fit", "x.csv", "--amp", "3", "--mass-g", "1001"],
                                  ["probe", "--freq", "20", "--amp", "3", "--mass-g", "0.09"]])
def test_the_command_line_names_the_same_mass_range(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--mass-g" in err and "[0.1, 1000] g" in err
