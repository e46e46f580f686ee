"""From probes to omega_n_hat (and alpha_hat) with uncertainty, by the paper's Lorentzian method or the atlas:
:func:`identify`, the one entry point, a call of the method's estimator
(:mod:`plate_env.identify.estimators`). The Lorentzian method itself is :mod:`plate_env.identify.lorentz` (its
names are kept here for callers).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from plate_env.core.probe import ProbeResult
from plate_env.core.probe_table import ProbeTable
from plate_env.identify.estimate import METHODS, Estimate
from plate_env.identify.estimators import ForwardName, make_estimator
from plate_env.identify.forward import ForwardModel
from plate_env.identify.lorentz import (
    extrapolated_peak,
    identify_lorentz,
    offset_intervals,
    positive_intervals,
    zero_interval_note,
)
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.identify.lab_calibration_file import LabCalibration

__all__ = ["METHODS", "extrapolated_peak", "identify", "identify_lorentz", "offset_intervals", "positive_intervals",
           "zero_interval_note"]


def _table(probes: Sequence[ProbeResult] | ProbeTable) -> ProbeTable:
    return probes if isinstance(probes, ProbeTable) else ProbeTable.from_results(list(probes))


def identify(probes: Sequence[ProbeResult] | ProbeTable, method: str = "atlas", physics: str = "tilelink",
             model: str = "pointmass", forward: ForwardModel | str | None = None, known: KnownInputs | None = None,
             calibration: LabCalibration | str | os.PathLike[str] | None = None, **options: Any) -> Estimate:
    """Estimate omega_n (and alpha) from probes at any plate amplitudes.

    ``method="atlas"`` (model-based, the default): the posterior of a forward model
    (:mod:`~plate_env.identify.inference`): ``forward`` (a :class:`~.forward.ForwardModel` or a shipped name such as
    ``"lab"``), else the model that made the data, ``"<physics>/<model>"``, conditioned on the known inputs (``known``,
    else those of the probes when they are :class:`ProbeResult`, else the paper's set-up). ``method="lorentz"``: the
    paper's Eq. (9) fit per amplitude and Eq. (10) calibration of ``physics``/``model`` (``physics="paper"``: the
    paper's coefficients). ``calibration`` (a :class:`~.lab_calibration_file.LabCalibration`, a CAL.json path or
    ``"paper"``): read the probes through what a lab's reference discs taught (``plate-env calibrate``); the data
    must match its amplitude and set-up.
    """
    if known is None and not isinstance(probes, ProbeTable):
        known = KnownInputs.from_specs(r.spec for r in probes)
    return make_estimator(method, ForwardName(physics, model), known, forward, calibration, **options).fit(
        _table(probes))
