"""The settings of one ``PlateRotation-v0`` env: :class:`EnvConfig`, every constructor argument, validated once.

``EnvConfig(**kwargs)`` checks each value as it is built (a ValueError naming the argument and the values it
allows, in the order the arguments are listed) and holds the checked values: numbers as floats, ranges as float
pairs, ``physics_options`` as a dict, ``calibration`` as the loaded
:class:`~plate_env.identify.lab_calibration_file.LabCalibration` (or None). What needs the physics backend -- can it
answer every probe the settings allow -- is checked by :func:`refuse_unanswerable` once the backend is built.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from plate_env.core import checks
from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectPrior, ObjectSpec
from plate_env.core.probe import MIN_PROBE_FREQ_HZ, WINDOW_RANGE_S, ProbeRefused, ProbeSpec
from plate_env.core.setup import B_P_RANGE_M, DEFAULT_MAX_PROBES, FREQ_RANGE_HZ, MAX_PROBES_RANGE, PAPER_SETUP
from plate_env.identify.estimate import METHODS
from plate_env.physics import PHYSICS_NAMES, make_physics
from plate_env.physics.interface import refuse_early

if TYPE_CHECKING:
    from plate_env.identify.estimators import ForwardName
    from plate_env.identify.lab_calibration_file import LabCalibration
    from plate_env.physics.interface import Physics

#: Mass of the hidden object before ``mass_variation``, kg (the paper's cheese slice).
MASS_KG = PAPER_SETUP.mass
#: The render modes the env offers (``render_mode=None``: none).
RENDER_MODES = ("rgb_array", "rgb_array_list", "human")
#: The constructor option that decides each quantity of the probes a backend may refuse (ProbeRefused.quantity).
OPTION_OF = {"f_p_hz": "f_band_hz", "a_p_deg": "amplitudes_deg", "omega_n": "omega_n_range_pi",
             "alpha": "alpha_range_deg", "b_p": "b_p_mm", "mass": "mass_variation", "diameter": "physics",
             "steps": "measure_range_s, settle_s or the physics' dt"}


@dataclass(frozen=True)
class EnvConfig:
    """Every argument of ``PlateRotation-v0`` (the table of :class:`~plate_env.env.rotation.PlateRotationEnv`'s
    docstring), checked on construction. Units in the names (Hz, deg, mm, s; ``omega_n_range_pi`` in pi rad/s)."""

    physics: str = "tilelink"
    physics_options: dict[str, Any] | None = None
    method: str = "atlas"
    omega_n_range_pi: tuple[float, float] = ObjectPrior.omega_n_range_pi
    alpha_range_deg: tuple[float, float] = ObjectPrior.alpha_range_deg
    mass_variation: float = 0.0
    f_band_hz: tuple[float, float] = (10.0, 40.0)
    amplitudes_deg: tuple[float, ...] = (3.0, 12.0)
    b_p_mm: float = PAPER_SETUP.b_p_mm
    max_probes: int = DEFAULT_MAX_PROBES
    max_sim_s: float | None = None
    measure_range_s: tuple[float, float] = (0.25, 2.0)
    settle_s: float = 0.5
    camera_fps: float = 30.0
    angle_noise_deg: float = 0.5
    cost_per_sim_s: float = 0.005
    error_cap: float = 1.0
    no_estimate_penalty: float = 1.0
    render_mode: str | None = None
    calibration: Any = None
    reveal_truth: bool = False

    def __post_init__(self) -> None:
        for name, value in _checked(self).items():
            object.__setattr__(self, name, value)

    @classmethod
    def of(cls, settings: dict[str, Any]) -> EnvConfig:
        """The config of the env's keyword arguments ``settings`` (TypeError naming an unknown one and the
        arguments, as a call with it would; ValueError naming a bad value)."""
        unknown = sorted(set(settings) - set(ARGUMENTS))
        if unknown:
            raise TypeError(f"PlateRotationEnv got an unexpected keyword argument {unknown[0]!r}; its arguments: "
                            f"{', '.join(ARGUMENTS)}")
        return cls(**settings)

    # ------------------------------------------------------------------ derived
    def corner_objects(self) -> list[ObjectSpec]:
        """The objects at the corners of the hidden-object ranges (omega_n, alpha, mass): with the band, amplitudes
        and windows' corners, the probes whose answers bound every probe the settings allow."""
        lo, hi = self.omega_n_range_pi
        masses = (MASS_KG * (1.0 - self.mass_variation), MASS_KG * (1.0 + self.mass_variation))
        return [ObjectSpec(omega_n=math.pi * w, alpha=math.radians(a), mass=m)
                for w in (lo, hi) for a in self.alpha_range_deg for m in sorted(set(masses))]

    def corner_probes(self, objects: list[ObjectSpec]) -> list[ProbeSpec]:
        """The probes of ``objects`` at every corner of the band, amplitudes and windows."""
        return [ProbeSpec(obj, PlateMotion.from_paper(f, a, self.b_p_mm), settle_s=self.settle_s, measure_s=m)
                for obj in objects for f in self.f_band_hz for a in self.amplitudes_deg for m in self.measure_range_s]

    def options(self) -> dict[str, Any]:
        """The backend's options as a dict (``physics_options``; empty for none)."""
        return dict(self.physics_options or {})


#: The names of the env's arguments, in the constructor's order.
ARGUMENTS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(EnvConfig))


#: The arguments an env shows as attributes of its own (``physics`` is the backend, ``render_mode`` Gymnasium's).
_VIEWED = frozenset(ARGUMENTS) - {"physics", "render_mode"}


class ConfigView:
    """``obj.<argument>`` of an object with a ``config`` (:class:`EnvConfig`): the checked value of the argument
    (``env.max_probes``; ``env.calibration``, the loaded lab calibration); read-only (AttributeError: the config is
    frozen, and the codec, spaces and task were built from it; make a new env)."""

    def __getattr__(self, name: str) -> Any:
        config = self.__dict__.get("config")
        if config is not None and name in _VIEWED:
            return getattr(config, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _VIEWED:
            raise AttributeError(f"{type(self).__name__}.{name} is its config's (EnvConfig, frozen): make a new env "
                                 f"with {name}={value!r}")
        super().__setattr__(name, value)


def build_physics(config: EnvConfig) -> Physics:
    """``make_physics(config.physics, **config.physics_options)``, an option the backend does not take or refuses
    named as a ``physics_options`` error."""
    name, options = config.physics, config.options()
    try:
        return make_physics(name, **options)
    except TypeError as exc:  # an unknown keyword
        raise ValueError(f"physics_options {options!r}: physics {name!r} does not take that option ({exc})") from None
    except ValueError as exc:
        raise ValueError(f"physics_options {options!r} for physics {name!r}: {exc}") from None


def forward_name(config: EnvConfig, physics: Physics) -> ForwardName:
    """The model that makes ``physics``' data, ``source/model`` (the backend's name when it declares neither)."""
    from plate_env.identify.estimators import ForwardName

    return ForwardName(getattr(physics, "source", config.physics), getattr(physics, "model", config.physics))


def refuse_unanswerable(config: EnvConfig, physics: Physics, objects: list[ObjectSpec], what: str) -> None:
    """Refuse (ValueError naming the option, ``what`` ``"option"``, or the quantity, ``"reset option"``) when
    ``physics`` cannot answer the probes ``config`` allows about ``objects``: every corner of the band, amplitudes and
    windows (the backends' limits are boxes)."""
    try:
        refuse_early(physics, config.corner_probes(objects))
    except ProbeRefused as exc:
        option = OPTION_OF.get(exc.quantity, exc.quantity) if what == "option" else exc.quantity
        raise ValueError(f"PlateRotationEnv {what} {option}: physics {config.physics!r} cannot answer the "
                         f"probes it allows: {exc}") from None


def _checked(c: EnvConfig) -> dict[str, Any]:
    """Each argument of ``c`` checked, in the order the env always checked them (the first bad one is named)."""
    if not isinstance(c.reveal_truth, (bool, np.bool_)):
        raise ValueError(f"reveal_truth = {c.reveal_truth!r} must be True or False")
    v: dict[str, Any] = {
        "render_mode": checks.one_of("render_mode", c.render_mode, (None, *RENDER_MODES)),
        "method": checks.one_of("method", c.method, METHODS),
        "omega_n_range_pi": checks.pair("omega_n_range_pi", c.omega_n_range_pi, 0.1, 300.0, "pi rad/s"),
        "alpha_range_deg": checks.pair("alpha_range_deg", c.alpha_range_deg, 1.0, 89.0, "deg"),
        "mass_variation": checks.real("mass_variation", c.mass_variation, 0.0, 1.0, open_hi=True),
        "f_band_hz": checks.pair("f_band_hz", c.f_band_hz, MIN_PROBE_FREQ_HZ, FREQ_RANGE_HZ[1], "Hz"),
        "amplitudes_deg": _amplitudes(c.amplitudes_deg),
    }
    v["b_p_mm"] = checks.real("b_p_mm", c.b_p_mm, B_P_RANGE_M[0] * 1e3, B_P_RANGE_M[1] * 1e3, unit="mm")
    v["max_probes"] = checks.integer("max_probes", c.max_probes, *MAX_PROBES_RANGE)
    v["max_sim_s"] = None if c.max_sim_s is None else checks.real("max_sim_s", c.max_sim_s, 0.0, 1e6, open_lo=True,
                                                                   unit="s")
    v["measure_range_s"] = checks.pair("measure_range_s", c.measure_range_s, 0.01, 60.0, "s")
    v["settle_s"] = checks.real("settle_s", c.settle_s, *WINDOW_RANGE_S, unit="s")
    v["camera_fps"] = checks.real("camera_fps", c.camera_fps, 1.0, 1e4, unit="Hz")
    v["angle_noise_deg"] = checks.real("angle_noise_deg", c.angle_noise_deg, 0.0, 90.0, unit="deg")
    v["cost_per_sim_s"] = checks.real("cost_per_sim_s", c.cost_per_sim_s, 0.0, 1e3)
    v["error_cap"] = checks.real("error_cap", c.error_cap, 0.0, 1e3, open_lo=True)
    v["no_estimate_penalty"] = checks.real("no_estimate_penalty", c.no_estimate_penalty, 0.0, 1e3)
    v["physics"] = checks.one_of("physics", c.physics, PHYSICS_NAMES)
    v["calibration"] = _calibration(c.calibration, v["amplitudes_deg"], v["b_p_mm"])
    if c.physics_options is not None and not isinstance(c.physics_options, dict):
        raise ValueError(f"physics_options = {c.physics_options!r} must be a dict of backend options or None")
    v["physics_options"] = dict(c.physics_options or {})
    v["reveal_truth"] = bool(c.reveal_truth)
    return v


def _amplitudes(values: Any) -> tuple[float, ...]:
    """The env's plate amplitudes: one or more distinct non-zero values within +-45 deg."""
    try:
        items = tuple(values)
    except TypeError:
        items = ()
    if not items:
        raise ValueError(f"amplitudes_deg = {values!r}: give one or more plate amplitudes in degrees")
    amps = tuple(checks.real(f"amplitudes_deg[{i}]", a, -45.0, 45.0, unit="deg") for i, a in enumerate(items))
    if 0.0 in amps or len(set(amps)) != len(amps):
        raise ValueError(f"amplitudes_deg = {values!r}: amplitudes must be distinct and non-zero")
    return amps


def _calibration(calibration: object, amplitudes_deg: tuple[float, ...], b_p_mm: float) -> LabCalibration | None:
    """The env's lab calibration (None: the estimate's own forward model), checked against the amplitudes and
    B_p the episodes use (ValueError naming the mismatch)."""
    if calibration is None:
        return None
    from plate_env.identify import lab_calibration_file as lcf

    if not isinstance(calibration, (lcf.LabCalibration, str, os.PathLike)):
        raise ValueError(f"calibration={calibration!r}: give a LabCalibration, a CAL.json path or 'paper'")
    if isinstance(calibration, lcf.LabCalibration):
        cal = calibration
    else:
        cal = lcf.load(calibration if isinstance(calibration, str) else Path(calibration))
    if tuple(float(a) for a in amplitudes_deg) != (cal.a_p_deg,):
        raise ValueError(f"calibration holds for A_p = {cal.a_p_deg:g} deg only: set amplitudes_deg=({cal.a_p_deg:g},) "
                         f"(got {tuple(amplitudes_deg)})")
    if abs(b_p_mm - cal.known.b_p * 1e3) > 0.02 * cal.known.b_p * 1e3:
        raise ValueError(f"calibration holds for B_p = {cal.known.b_p * 1e3:g} mm, the env's b_p_mm is {b_p_mm:g}")
    return cal
