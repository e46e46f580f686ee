"""The identification task of ``PlateRotation-v0`` (panda-gym's ``Task`` beside its ``Robot``): what an episode is
for, apart from the physics that answers its probes and the codec that lays out its observations.

:class:`IdentificationTask` says how a probe is charged (``cost_per_sim_s`` per simulated second), when the probe
budget is spent (``max_probes`` probes or ``max_sim_s`` simulated seconds), how the episode's estimate is made (the
:class:`~plate_env.identify.estimators.Estimator` of the env's method on the forward model of its physics, or its
lab calibration) and how it is scored (its relative error, capped at ``error_cap``; ``no_estimate_penalty`` when
there is none). It holds no episode: the probes and the incremental posterior are the episode state's
(:mod:`plate_env.env.state`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from plate_env.core import checks
from plate_env.core.objects import ObjectPrior, ObjectSpec
from plate_env.env.config import MASS_KG, EnvConfig
from plate_env.identify.estimate import Estimate
from plate_env.identify.estimators import AtlasEstimator, Estimator, ForwardName, make_estimator
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.identify.posterior_state import PosteriorState

#: Keys ``reset(options=...)`` accepts: the hidden object's omega_n (rad/s), alpha (rad), mass (kg).
RESET_OPTIONS = ("omega_n", "alpha", "mass")


@dataclass(frozen=True)
class IdentificationTask:
    """Reward, termination and estimate of the env ``config`` whose probes the model ``forward`` makes (the
    physics' ``source/model``: whose forward model and Eq. (10) lines read them)."""

    config: EnvConfig
    forward: ForwardName

    @staticmethod
    def reset_values(options: dict[str, Any] | None) -> dict[str, float]:
        """``reset(options=...)`` checked: only the keys :data:`RESET_OPTIONS`, each a real number (ValueError
        naming the option); pure, so a reset is refused before it draws."""
        known = checks.known_keys("reset options", options, RESET_OPTIONS)
        return {k: checks.real(f"reset option {k}", v) for k, v in known.items()}

    def hidden_object(self, rng: np.random.Generator, options: dict[str, Any] | None) -> ObjectSpec:
        """The episode's hidden object: omega_n (rad/s) and alpha (rad) drawn from the prior ranges, the mass (kg)
        13.6 g times 1 + ``mass_variation`` * U(-1, 1), always drawn in this order from ``rng``; the quantities the
        reset ``options`` give (:meth:`reset_values`) replace their draws (ValueError naming them when no object
        has them)."""
        given = self.reset_values(options)
        c = self.config
        drawn_omega, drawn_alpha = ObjectPrior(c.omega_n_range_pi, c.alpha_range_deg).draw(rng)
        drawn = {"omega_n": drawn_omega, "alpha": drawn_alpha,
                 "mass": MASS_KG * (1.0 + c.mass_variation * rng.uniform(-1.0, 1.0))}  # drawn either way
        try:
            return ObjectSpec(**{**drawn, **given}, name="hidden")
        except ValueError as exc:
            raise ValueError(f"reset options {checks.known_keys('reset options', options, RESET_OPTIONS)!r}: "
                             f"{exc}") from None

    def estimator(self, known: KnownInputs) -> Estimator:
        """The episode's estimator for the episode's ``known`` inputs: the env's method on :attr:`forward`'s model,
        or its lab calibration."""
        return make_estimator(self.config.method, self.forward, known, calibration=self.config.calibration)

    def start(self, known: KnownInputs) -> PosteriorState | bool | str:
        """The estimator's incremental posterior (its ``start()``), False when it refits from scratch, or the reason
        there is none (the ValueError it raised, as a str)."""
        try:
            state = self.estimator(known).start()
        except ValueError as exc:
            return str(exc)
        return False if state is None else state

    def no_estimate(self, reason: str) -> Estimate:
        """No estimate, for ``reason``, by the env's method."""
        return Estimate(ok=False, method=self.config.method, reason=reason)

    def reads_forward_model(self, known: KnownInputs) -> bool:
        """Whether the episode's estimate reads a forward model that may be replaced (the atlas method without a lab
        calibration): what ``use_estimate_model`` needs."""
        return isinstance(self.estimator(known), AtlasEstimator)

    def probe_cost(self, sim_s: float) -> float:
        """What a probe that took ``sim_s`` simulated seconds costs (subtracted from the step's reward)."""
        return self.config.cost_per_sim_s * sim_s

    def budget_spent(self, n_probes: int, sim_s: float) -> bool:
        """Whether ``n_probes`` probes taking ``sim_s`` simulated seconds end the episode (``max_probes`` run, or
        ``max_sim_s`` reached)."""
        c = self.config
        return n_probes >= c.max_probes or (c.max_sim_s is not None and sim_s >= c.max_sim_s)

    def charge(self, estimate: Estimate, omega_n: float) -> tuple[float, float | None]:
        """What the episode's end costs (subtracted from the reward) and the estimate's relative error against the
        hidden ``omega_n`` (rad/s): the error capped at ``error_cap``, or ``no_estimate_penalty`` and None when there
        is no estimate."""
        error = estimate.relative_error(omega_n) if estimate.ok else None
        if error is not None:
            return min(error, self.config.error_cap), error
        return self.config.no_estimate_penalty, None
