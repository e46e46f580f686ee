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
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.estimate import METHODS, Estimate
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.identify.calibration import Calibration
    from plate_env.identify.forward import ForwardModel
    from plate_env.identify.lab_calibration_file import LabCalibration
    from plate_env.identify.posterior_state import PosteriorState
    from plate_env.identify.unknown_origin import ReadingsState


#: The forward model of data of unknown origin (every physics pooled): its readings go through every physics'
#: statement (:func:`unknown_origin`), the estimate's and the incremental posterior's alike.
POOL = "lab"


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

    @property
    def method(self) -> str: ...

    def fit(self, table: ProbeTable) -> Estimate: ...

    def start(self) -> PosteriorState | None: ...


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
        from plate_env.identify.forward import shipped_model

        return self.model if self.model is not None else shipped_model(str(self.forward), self.known)

    def fit(self, table: ProbeTable) -> Estimate:
        from plate_env.identify.inference import identify_atlas

        fm = self.forward_model()
        est = identify_atlas(table, fm)
        return unknown_origin(est, table, self.known) if fm.name == POOL else est

    def start(self) -> PosteriorState:
        from plate_env.identify.posterior_state import PosteriorState

        fm = self.forward_model()
        if fm.name != POOL:
            return PosteriorState(fm)
        from plate_env.identify.unknown_origin import ReadingsState

        readings = ReadingsState(self.known)  # each physics' posterior kept, fed the probes as they come
        return PosteriorState(fm, finish=lambda est, table: unknown_origin(est, table, self.known, readings))

    def _key(self) -> tuple[object, ...]:
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
    known: KnownInputs = field(default_factory=KnownInputs)
    method: ClassVar[str] = "lorentz"

    def __eq__(self, other: object) -> bool:  # the same line source, the same calibrations object (or none)
        return isinstance(other, LorentzEstimator) and (self.name, id(self.calibrations), self.known) == (
            other.name, id(other.calibrations), other.known)

    def __hash__(self) -> int:
        return hash((self.name, id(self.calibrations), self.known))

    def fit(self, table: ProbeTable) -> Estimate:
        from plate_env.identify.lorentz import identify_lorentz

        est = identify_lorentz(table, self.name.physics, self.name.model, calibrations=self.calibrations)
        if _shipped(str(self.name)):  # the model that made the data is known (simulation): its posterior's contract
            return gated(est, table, str(self.name), self.known)
        # the paper's lines, real data: lab's edge rule, and the hump Eq. (9) reads (always: it is the method's own)
        return gated_unknown_origin(est, table, self.known, require_hump=True)

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

        est = identify_calibrated(table, self.calibration, self.known)
        return gated_unknown_origin(est, table, self.known or self.calibration.known, self.calibration.forward)

    def start(self) -> None:
        return None


def make_estimator(method: str = "atlas", name: ForwardName | str = ForwardName("tilelink", "pointmass"),
                   known: KnownInputs | None = None, forward: ForwardModel | str | None = None,
                   calibration: LabCalibration | str | os.PathLike[str] | None = None,
                   **options: Any) -> Estimator:
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
        return LorentzEstimator(name, known=known or KnownInputs(), **options)
    if options:
        raise TypeError(f"identify(method='atlas') takes no options {sorted(options)}")
    known = known or KnownInputs()
    if forward is None or isinstance(forward, str):
        return AtlasEstimator(forward or name, known)
    return AtlasEstimator(forward.name, known, model=forward)


def _shipped(name: str) -> bool:
    from plate_env.surrogate.catalog import read_catalog

    return name in read_catalog()


#: A sweep whose best Lorentzian hump explains less than this share of its variance (R^2) shows no resonance: a
#: reading of it through Eq. (10) lines or a lab calibration is no estimate. Measured (experiments/estimate_contract.py,
#: experiments/results/estimate_contract.md): honest sweeps and the paper's curves 0.98-1.0, uniform noise 0.07.
HUMP_R2_MIN = 0.5


def hump_reason(table: ProbeTable) -> str | None:
    """Why ``table`` shows no measured resonance hump at some amplitude (None when each shows one): the Lorentzian
    fit of Eq. (9) fails (flat, not positive, too few stable probes), its top lies outside the probes it used
    (:func:`plate_env.identify.lorentz.extrapolated_peak`), or it explains less than :data:`HUMP_R2_MIN` of the
    sweep. Model-free: what a reading that corrects the models' discrepancy (a calibration, the paper's lines) still
    needs from the data."""
    import numpy as np

    from plate_env.identify.fitting import fit_lorentzian
    from plate_env.identify.lorentz import extrapolated_peak

    for amp in table.amplitudes():
        sub = table.subset(np.isclose(table.a_p_deg, amp))
        fit = fit_lorentzian(sub.f_p_hz, sub.omega_b_deg_s, sub.stderr_deg_s if np.any(sub.stderr_deg_s > 0)
                             else None, sub.unstable)
        if not fit.ok:
            return f"A_p = {amp:g} deg: {fit.reason}"
        if (why := extrapolated_peak(fit, sub.f_p_hz)) is not None:
            return f"A_p = {amp:g} deg: {why}"
        if fit.r2 < HUMP_R2_MIN:
            return (f"A_p = {amp:g} deg: the best Lorentzian hump explains R^2 = {fit.r2:.2f} of the sweep (< "
                    f"{HUMP_R2_MIN:g}): no resonance was measured")
    return None


def gated_unknown_origin(est: Estimate, table: ProbeTable, known: KnownInputs, forward: str = "lab",
                         require_hump: bool = False) -> Estimate:
    """The estimate contract for a reading that corrects the models' discrepancy (a lab calibration, the paper's
    Eq. (10) lines on real data). The ``forward`` posterior of the probes is computed: an object it places at the
    edge of its identifiable range gets its bound, not the reading; a sweep that fails its predictive check must
    show a measured resonance hump (:func:`hump_reason`), else no estimate (data neither the models explain nor
    showing a resonance: zeros, flat, negative, noise). A failed check alone does not refuse: a calibration exists
    because real sweeps differ from every model (the paper's Fig. 7a curve fails it, p at its floor), and a sweep
    the members explain needs no hump (a rigid disc's sweep half unstable) unless ``require_hump`` (the Lorentz
    method, which reads nothing but the hump). The check is carried (``check``); measured:
    experiments/results/estimate_contract.md."""
    import dataclasses

    if not est.ok:
        return est
    base: dict[str, Any] = dict(ok=False, method=est.method, n_probes=est.n_probes, n_unstable=est.n_unstable,
                                forward=est.forward, fits=est.fits)
    try:
        from plate_env.identify.inference import identify_atlas

        gate = identify_atlas(table, AtlasEstimator(forward, known).forward_model())
    except ValueError:  # no member for these known inputs: nothing to check against
        gate = None
    check = None if gate is None else gate.check
    if require_hump or check is None or not check.passed:
        why = hump_reason(table)
        if why is not None:
            failed = gate is not None and check is not None and not check.passed
            said = f"{gate.reason}; and " if failed and gate is not None else ""
            return Estimate(reason=f"no {est.method} reading of these probes: {said}they show no resonance ({why})",
                            check=check, **base)
    if gate is not None and gate.bound is not None:
        return Estimate(reason=f"the {forward!r} posterior of these probes gives a bound, so the {est.method} "
                        f"reading of them is not given: {gate.reason}", bound=gate.bound, beyond=gate.beyond,
                        check=check, **base)
    return unknown_origin(dataclasses.replace(est, check=check), table, known)


def unknown_origin(est: Estimate, table: ProbeTable, known: KnownInputs,
                   readings: ReadingsState | None = None) -> Estimate:
    """``est``, a reading of data of unknown origin, unless the shipped physics place its disc beyond their
    range (issue 37 item 1, :func:`plate_env.identify.unknown_origin.verdict`; ``readings``: an episode's
    incremental statements): then no estimate, with the rule's bound, or none."""
    if not est.ok:
        return est
    from plate_env.identify.unknown_origin import verdict

    v = verdict(table, known, readings)
    if v is None:
        return est
    return Estimate(ok=False, method=est.method, reason=f"no {est.method} reading of these probes: {v.reason}",
                    bound=v.bound, n_probes=est.n_probes, n_unstable=est.n_unstable, forward=est.forward,
                    fits=est.fits, check=est.check)


def gated(est: Estimate, table: ProbeTable, forward: str, known: KnownInputs) -> Estimate:
    """The estimate contract for a method without a posterior of its own (the Lorentz lines, a lab calibration):
    its number stands only where the atlas method on ``forward`` (the members it reads, or the model that made the
    data) would answer too. The probes go through that posterior's predictive check and edge rules
    (:func:`plate_env.identify.inference.identify_atlas`): data the model cannot explain get no estimate (the
    check's reason), an object piled at the edge of the identifiable range gets that posterior's bound, a friction
    angle at its edge or probes no member describes no estimate; otherwise ``est`` carries the check it passed.
    ``est`` without an estimate is returned as it is (its own reason)."""
    import dataclasses

    if not est.ok:
        return est
    gate = AtlasEstimator(forward, known).fit(table)
    if gate.ok:
        return dataclasses.replace(est, check=gate.check)
    return Estimate(ok=False, method=est.method, reason=f"the {forward!r} posterior of these probes gives no "
                    f"estimate, so the {est.method} reading of them is not given: {gate.reason}", bound=gate.bound,
                    check=gate.check, n_probes=est.n_probes, n_unstable=est.n_unstable, forward=est.forward,
                    fits=est.fits)


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
