"""Readings of data of unknown origin beyond the identifiable range (issue 37 item 1).

A calibration or Eq. (10) lines read a lab's sweep whose physics no one names; whether its disc lies beyond the range
the models identify depends on that physics (:mod:`plate_env.identify.identifiability` asks one model). Here every
shipped physics is asked (:func:`beyond_every_physics`). Measured: experiments/results/estimate_contract.md,
section 4.
"""

from __future__ import annotations

from plate_env.core.probe_table import ProbeTable
from plate_env.surrogate.conditioning import KnownInputs

#: The shipped physics whose forward models are extended beyond their range: what a reading of data of unknown
#: origin asks (:func:`beyond_every_physics`).
PHYSICS_MODELS = ("tilelink/pointmass", "tilelink/rigid_fast", "pybullet/pybullet")


def beyond_every_physics(table: ProbeTable, known: KnownInputs) -> str | None:
    """Why probes of unknown origin (a lab's sweep read through a calibration or Eq. (10) lines) are placed beyond
    the identifiable range, or None. Each shipped physics (:data:`PHYSICS_MODELS`) reads them by the atlas method:
    one that answers inside its range lets the reading stand (the probes may come from an in-range disc of that
    physics), and so does an extended one that piles alpha at its edge without placing omega_n beyond; one whose
    predictive check fails does not explain them, and one without an extended model cannot look beyond its range:
    neither is asked further. When every physics that explains them places the
    disc beyond its range (a bound, or mass beyond both ends), the reason is returned; no bound is given, since
    which physics made the data is not known."""
    from plate_env.identify.forward import shipped_model
    from plate_env.identify.identifiability import extended_model
    from plate_env.identify.inference import identify_atlas

    said = []
    for name in PHYSICS_MODELS:
        try:
            fm = shipped_model(name, known)
        except ValueError:  # no member for these known inputs: that physics cannot be asked
            return None
        est = identify_atlas(table, fm)
        if est.ok:
            return None
        if extended_model(fm) is None or (est.check is not None and not est.check.passed):
            continue  # a physics that cannot look beyond its range, or does not explain the probes, says nothing
        if est.bound is None and "cannot tell" not in (est.reason or ""):
            return None
        said.append(f"{name}: {est.reason}")
    if not said:
        return None
    return "every shipped physics that explains these probes places the disc beyond its range (" + "; ".join(said) + ")"
