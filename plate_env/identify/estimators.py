"""One estimator object per identification method (as lmfit's ``Model.fit`` returns a ``ModelResult``): an
:class:`Estimator` is a frozen value with ``fit(table) -> Estimate`` and ``start() -> PosteriorState | None`` (the
incremental posterior a method keeps probe by probe; None for a method that refits from scratch).

* :class:`AtlasEstimator`: a forward model's posterior (:func:`plate_env.identify.inference.identify_atlas`), its
  predictive check and edge rules included;
* :class:`LorentzEstimator`: the paper's Eq. (9) fit per amplitude and Eq. (10) line
  (:func:`plate_env.identify.lorentz.identify_lorentz`);
* :class:`CalibratedEstimator`: the probes read through a lab's reference-disc calibration
  (:func:`plate_env.identify.lab_calibration_file.identify_calibrated`).

:func:`make_estimator` is the registry: the one place a method's name (``"atlas"``, ``"lorentz"``) is turned into an
estimator; the env, the episode loop, the agents, the benchmark, the CLI and :func:`plate_env.identify.identify`
hold estimators. :class:`ForwardName` is the one typed name of "physics/model" (the model that made the data).

``fit`` raises ValueError on input the method cannot read (an unknown forward model, a calibration of another
set-up), as :func:`plate_env.identify.identify` does; :func:`fit_or_refuse` turns that into no estimate with the
reason (what an episode answers).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, Protocol, runtime_checkable

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.estimate import METHODS, Estimate
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.identify.calibration import Calibration
    from plate_env.identify.forward import ForwardModel
    from plate_env.identify.lab_calibration_file import LabCalibration
    from plate_env.identify.posterior_state import PosteriorState


@dataclass(frozen=True)
class ForwardName:
    """The model that made the data, ``"<physics>/<model>"`` (e.g. ``tilelink/pointmass``): whose forward model
    (:func:`plate_env.identify.forward.load_forward_model`) and Eq. (10) lines apply. Parsed once
    (:meth:`parse`), written by ``str()``."""

    physics: str
    model: str

    def __post_init__(self) -> None:
        for part, value in (("physics", self.physics), ("model", self.model)):
            if not isinstance(value, str) or not value or "/" in value:
                raise ValueError(f"ForwardName {part} = {value!r}: a non-empty name without '/'")

    @classmethod
    def parse(cls, text: str) -> ForwardName:
        """``"physics/model"`` as a :class:`ForwardName`; ValueError naming the text otherwise."""
        physics, slash, model = str(text).partition("/")
        if not slash:
            raise ValueError(f"{text!r} is not a 'physics/model' name (e.g. 'tilelink/pointmass')")
        return cls(physics, model)

    def __str__(self) -> str:
        return f"{self.physics}/{self.model}"


@runtime_checkable
class Estimator(Protocol):
    """What every identification method offers: ``method`` (the name in :attr:`Estimate.method`), ``fit(table)``
    (the estimate of a probe table; ValueError on input the method cannot read) and ``start()`` (an incremental
    :class:`~plate_env.identify.posterior_state.PosteriorState` whose ``estimate()`` equals ``fit`` of the probes
    added, or None when the method refits from scratch)."""

    method: str

    def fit(self, table: ProbeTable) -> Estimate: ...

    def start(self) -> PosteriorState | None: ...


#: Shipped forward models loaded per (name, known inputs), the latest few kept (objects of varied mass).
_LOADED: dict[tuple[str, KnownInputs], ForwardModel] = {}
_LOADED_MAX = 8


def _load(name: str, known: KnownInputs) -> ForwardModel:
    from plate_env.identify.forward import load_forward_model

    key = (name, known)
    if key not in _LOADED:
        if len(_LOADED) >= _LOADED_MAX:
            _LOADED.clear()
        _LOADED[key] = load_forward_model(name, known)
    return _LOADED[key]


@dataclass(frozen=True, eq=False)
class AtlasEstimator:
    """A forward model's posterior. ``forward``: a shipped forward model's name (``"lab"``, a :class:`ForwardName`
    such as ``tilelink/pointmass``), loaded conditioned on ``known``; or ``model``, a
    :class:`~plate_env.identify.forward.ForwardModel` given as is (an agent's own, e.g. with its design blur).
    Two estimators are equal when they read the same shipped model for the same known inputs, or the same given
    model object."""

    forward: str | ForwardName = "lab"
    known: KnownInputs = field(default_factory=KnownInputs)
    model: ForwardModel | None = None
    method: ClassVar[str] = "atlas"

    def forward_model(self) -> ForwardModel:
        """The forward model read (ValueError when a shipped one has no member for the known inputs)."""
        return self.model if self.model is not None else _load(str(self.forward), self.known)

    def fit(self, table: ProbeTable) -> Estimate:
        from plate_env.identify.inference import identify_atlas

        return identify_atlas(table, self.forward_model())

    def start(self) -> PosteriorState:
        from plate_env.identify.posterior_state import PosteriorState

        return PosteriorState(self.forward_model())

    def _key(self) -> tuple:
        return (str(self.forward), self.known) if self.model is None else ("given", id(self.model))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, AtlasEstimator) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())


@dataclass(frozen=True, eq=False)
class LorentzEstimator:
    """The paper's method: Eq. (9) fitted per plate amplitude, f0 mapped through that amplitude's Eq. (10) line of
    ``name`` (``physics="paper"``: the paper's coefficients), or through ``calibrations`` given per amplitude."""

    name: ForwardName = ForwardName("tilelink", "pointmass")
    calibrations: dict[float, Calibration] | None = None
    method: ClassVar[str] = "lorentz"

    def __eq__(self, other: object) -> bool:  # the same line source, the same calibrations object (or none)
        return isinstance(other, LorentzEstimator) and (self.name, id(self.calibrations)) == (
            other.name, id(other.calibrations))

    def __hash__(self) -> int:
        return hash((self.name, id(self.calibrations)))

    def fit(self, table: ProbeTable) -> Estimate:
        from plate_env.identify.lorentz import identify_lorentz

        return identify_lorentz(table, self.name.physics, self.name.model, calibrations=self.calibrations)

    def start(self) -> None:
        return None


@dataclass(frozen=True, eq=False)
class CalibratedEstimator:
    """The probes read through a lab's reference-disc calibration (a
    :class:`~plate_env.identify.lab_calibration_file.LabCalibration`), for the lab's ``known`` inputs (None: the
    calibration's own)."""

    calibration: LabCalibration
    known: KnownInputs | None = None
    method: ClassVar[str] = "calibrated"

    def __eq__(self, other: object) -> bool:  # the same calibration object for the same known inputs
        return isinstance(other, CalibratedEstimator) and (id(self.calibration), self.known) == (
            id(other.calibration), other.known)

    def __hash__(self) -> int:
        return hash((id(self.calibration), self.known))

    def fit(self, table: ProbeTable) -> Estimate:
        from plate_env.identify.lab_calibration_file import identify_calibrated

        return identify_calibrated(table, self.calibration, self.known)

    def start(self) -> None:
        return None


def make_estimator(method: str = "atlas", name: ForwardName | str = ForwardName("tilelink", "pointmass"),
                   known: KnownInputs | None = None, forward: ForwardModel | str | None = None,
                   calibration: LabCalibration | str | os.PathLike | None = None, **options) -> Estimator:
    """The registry: the estimator of ``method`` (``"atlas"`` or ``"lorentz"``) for data made by ``name``.

    ``forward``: the atlas method's forward model (a shipped name or a ForwardModel; default ``name``'s);
    ``calibration``: read through a lab calibration instead (a LabCalibration, a CAL.json path or ``"paper"``; no
    method, forward or options with it); ``options``:
    the Lorentz method's ``calibrations``. ValueError naming the method or the option otherwise."""
    if calibration is not None:
        if method != "atlas" or forward is not None or options:
            raise ValueError("identify(calibration=...) reads the probes through the calibration's own members: "
                             "give no method, forward or options with it")
        from plate_env.identify import lab_calibration_file as lcf

        cal = calibration if isinstance(calibration, lcf.LabCalibration) else lcf.load(calibration)
        return CalibratedEstimator(cal, known)
    if method not in METHODS:
        raise ValueError(f"unknown identification method {method!r}; choose one of {METHODS}")
    name = name if isinstance(name, ForwardName) else ForwardName.parse(name)
    if method == "lorentz":
        return LorentzEstimator(name, **options)
    if options:
        raise TypeError(f"identify(method='atlas') takes no options {sorted(options)}")
    known = known or KnownInputs()
    if forward is None or isinstance(forward, str):
        return AtlasEstimator(forward or name, known)
    return AtlasEstimator(forward.name, known, model=forward)


def fit_or_refuse(estimator: Estimator, table: ProbeTable) -> Estimate:
    """``estimator.fit(table)``, or no estimate with the reason: no probes, or the ValueError ``fit`` raised."""
    if len(table) == 0:
        return Estimate(ok=False, method=estimator.method, reason="no probes")
    try:
        return estimator.fit(table)
    except ValueError as exc:
        return Estimate(ok=False, method=estimator.method, reason=str(exc))


#: Whether a method's estimate reads a forward model (an agent's ``forward=`` option applies to it).
READS_FORWARD_MODEL = {"atlas": True, "lorentz": False}


def agent_estimator(method: str, own: ForwardModel | None, env_method: str, env_estimator: Estimator,
                    name: ForwardName, known: KnownInputs) -> Estimator:
    """The estimator of an agent that estimates by ``method`` (its ``method`` attribute) through ``own`` (the
    forward model it chose its probes on, or None) in an env made with ``env_method`` whose estimator is
    ``env_estimator``: its own model's posterior when it has one, else the env's estimator when the agent's method is
    the env's (a lab calibration of the env included), else its method's estimator of ``name``'s data."""
    if own is not None:
        return AtlasEstimator(own.name, known, model=own)
    if method == env_method:
        return env_estimator
    return make_estimator(method, name, known)
