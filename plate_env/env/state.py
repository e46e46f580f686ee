"""The state of one ``PlateRotation-v0`` episode, and the one step every form of the env takes.

:class:`EpisodeState` holds what an episode has done (the hidden object, the probes as the camera measured them,
the simulated seconds, the observation's rows, the incremental posterior) and turns an action into a probe and a
probe's result into ``(observation, reward, terminated, truncated, info)``; it runs no physics. :func:`step_episodes`
is the step: every action checked, then every probe planned (its placement drawn), then one batched physics call,
then every result recorded. :class:`~plate_env.env.rotation.PlateRotationEnv` steps its one episode with it,
:class:`~plate_env.env.vector.PlateRotationVectorEnv` its sub-environments' episodes in one call.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from plate_env.core import jit
from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectSpec
from plate_env.core.probe import ProbeResult, ProbeSpec
from plate_env.core.probe_table import ProbeTable
from plate_env.env import info as info_schema
from plate_env.env.codec import Codec
from plate_env.env.config import EnvConfig
from plate_env.env.render import Scene
from plate_env.env.task import IdentificationTask
from plate_env.identify.estimate import Estimate
from plate_env.identify.estimators import Estimator, fit_or_refuse
from plate_env.physics.camera import camera_omega_b
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.identify.forward import ForwardModel
    from plate_env.identify.posterior_state import PosteriorState
    from plate_env.physics.interface import Physics

#: One probe as the camera measured it: f_p (Hz), A_p (deg), omega_B (deg/s, 0 when unstable), its standard error
#: (deg/s), unstable, the window (s).
Row = tuple[float, float, float, float, bool, float]
#: What a step returns: observation, reward, terminated, truncated, info.
Step = tuple[np.ndarray, float, bool, bool, dict[str, Any]]


class EpisodeState:
    """One episode of an env with settings ``config``, task ``task`` and layout ``codec``: empty (``done``) until
    :meth:`reset`. ``on_step(probed, over)``, when set, is called at the end of every step (the env's frames)."""

    def __init__(self, config: EnvConfig, task: IdentificationTask, codec: Codec) -> None:
        self.config = config
        self.task = task
        self.codec = codec
        self.obj: ObjectSpec | None = None
        self.rows: list[Row] = []
        self.results: list[ProbeResult] = []
        self.sim_s = 0.0
        self.wall_s = 0.0
        self.done = True
        self.last: ProbeResult | None = None
        #: The episode's PosteriorState, False (the estimator refits from scratch) or why there is none; made lazily.
        self.posterior: PosteriorState | bool | str | None = None
        self.obs_rows = np.zeros(codec.obs_dim, dtype=np.float32)  # the probes' observation rows, each written once
        self.on_step: Callable[[bool, bool], None] | None = None

    def reset(self, obj: ObjectSpec) -> None:
        """Start an episode that hides ``obj``: no probes yet."""
        self.obj = obj
        self.rows, self.results = [], []
        self.obs_rows = np.zeros(self.codec.obs_dim, dtype=np.float32)
        self.sim_s = self.wall_s = 0.0
        self.done = False
        self.last = None
        self.posterior = None

    # ------------------------------------------------------------------ a step
    def check(self, action: object) -> np.ndarray:
        """Refuse a step before anything happens: an episode not reset or over, a bad action
        (:func:`check_action`); the checked action otherwise. Pure: no state changes, no random draw."""
        if self.obj is None or self.done:
            raise RuntimeError("call reset() before step() (the episode is over)")
        return check_action(action)

    def plan(self, a: np.ndarray, rng: np.random.Generator) -> ProbeSpec | None:
        """The probe a checked action asks for, placed from ``rng`` (a random yaw and offset), or None to stop (a
        stop before the first probe is ignored: the probe runs)."""
        if a[3] > 0 and self.rows:
            return None
        f, a_p, window = self.codec.decode(a)
        motion = PlateMotion.from_paper(f, a_p, self.config.b_p_mm)
        spec = ProbeSpec(self._hidden(), motion, settle_s=self.config.settle_s, measure_s=window, record_trace=True)
        return spec.perturbed(rng)

    def finish(self, result: ProbeResult | None, rng: np.random.Generator) -> Step:
        """Record the probe's ``result`` (None: the action stopped), the camera's noise drawn from ``rng``; the
        step's reward (the probe's cost, the estimate's charge at the end), termination and info."""
        reward = 0.0
        if result is not None:
            omega, se = camera_omega_b(result, rng, self.config.camera_fps, self.config.angle_noise_deg)
            if result.unstable:
                omega, se = 0.0, 0.0
            spec = result.spec
            self.rows.append((spec.motion.freq_hz, spec.motion.a_p_deg, omega, se, result.unstable, spec.measure_s))
            k = len(self.rows) - 1
            if k < self.config.max_probes:  # the observation's row of this probe, written once
                self.codec.put_row(self.obs_rows, k, self.rows[k])
            self.results.append(result)
            self.sim_s += result.sim_s
            self.wall_s += result.wall_s
            self.last = result
            reward -= self.task.probe_cost(result.sim_s)
        terminated = result is None or self.task.budget_spent(len(self.rows), self.sim_s)
        if terminated:
            self.done = True
            est = self.estimate()
            charge, error = self.task.charge(est, self._hidden().omega_n)
            reward -= charge
            info = self.info(final=True, estimate=est, error=error)
            jit.episode_ended()  # a process that runs many episodes loads the compiled kernels (plate_env.core.jit)
        else:
            info = self.info()
        if self.on_step is not None:
            self.on_step(result is not None, terminated)
        return self.observation(), float(reward), bool(terminated), False, info

    # ------------------------------------------------------------------ views
    def observation(self) -> np.ndarray:
        """``Codec.observation`` of the probes so far, from the rows written as each probe arrived."""
        c = self.config
        sim_left = 1.0 - self.sim_s / c.max_sim_s if c.max_sim_s else 1.0
        return self.codec.completed(self.obs_rows, 1.0 - len(self.rows) / c.max_probes, sim_left)

    def info(self, final: bool = False, estimate: Estimate | None = None,
             error: float | None = None) -> dict[str, Any]:
        """The step's info (:mod:`plate_env.env.info`: every key on every step): the hidden object on the
        terminating step (``final``) or with ``reveal_truth``, the estimate and its error on the terminating step."""
        obj = self.obj
        truth = (final or self.config.reveal_truth) and obj is not None
        v: dict[str, Any] = {"truth_revealed": truth, "probes": len(self.rows), "sim_s": self.sim_s,
                             "estimate.ok": False, "estimate.check.ok": False, "last_probe.ok": self.last is not None}
        if truth and obj is not None:
            v.update(omega_n_true_rad_s=obj.omega_n, alpha_true_rad=obj.alpha, mass_true_kg=obj.mass)
        if self.last is not None:
            p = self.last.to_dict()
            _, _, omega, se, unstable, _ = self.rows[-1]  # the camera's measurement: the observation's and the table's
            v.update({"last_probe.f_p_hz": p["f_p_hz"], "last_probe.a_p_deg": p["a_p_deg"],
                      "last_probe.b_p_mm": p["b_p_mm"], "last_probe.omega_b_deg_s": omega,
                      "last_probe.stderr_deg_s": se, "last_probe.unstable": unstable,
                      "last_probe.reason": p["reason"], "last_probe.sim_s": p["sim_s"],
                      "last_probe.periods_measured": p["periods_measured"]})
            if truth:
                v.update({"last_probe.omega_n_rad_s": p["omega_n_rad_s"], "last_probe.alpha_deg": p["alpha_deg"],
                          "last_probe.mass_g": p["mass_g"]})
        if final:
            v["wall_s"] = self.wall_s
            v["relative_error"] = error
            if estimate is not None:
                v.update(info_schema.estimate_values(estimate))
        return info_schema.build(v)

    def table(self) -> ProbeTable:
        """The probes of this episode as the camera measured them."""
        if not self.rows:
            return ProbeTable.from_arrays([], [], [])
        f, a, w, se, un, _ = zip(*self.rows, strict=True)
        return ProbeTable.from_arrays(f, a, w, se, un)

    def known_inputs(self) -> KnownInputs:
        """What a lab would know of this episode's set-up: B_p and the disc's mass and diameter (weighed and
        measured, unlike its stiffness); the paper's set-up before the first reset."""
        b_p = self.config.b_p_mm * 1e-3
        return KnownInputs(b_p=b_p) if self.obj is None else KnownInputs(b_p=b_p, mass=self.obj.mass,
                                                                          diameter=self.obj.diameter)

    # ------------------------------------------------------------------ the estimate
    def estimator(self) -> Estimator:
        """The task's estimator for this episode's known inputs."""
        return self.task.estimator(self.known_inputs())

    def estimate(self) -> Estimate:
        """The estimate of the probes so far: the incremental posterior's, brought up to date with the probes not
        in it, when the estimator has one; else fitted from scratch; no estimate with the reason when none can be
        made."""
        if not self.rows:
            return self.task.no_estimate("no probes")
        state = self.posterior_state()
        if isinstance(state, str):
            return self.task.no_estimate(state)
        if state is None:
            return fit_or_refuse(self.estimator(), self.table())
        if state.n_probes < len(self.rows):
            state.add_table(self.table(), start=state.n_probes)
        return state.estimate()

    def posterior_state(self) -> PosteriorState | str | None:
        """The episode's incremental posterior (made on first use), None for an estimator that refits from scratch,
        or the reason there is none (a str)."""
        if self.posterior is None:
            self.posterior = self.task.start(self.known_inputs())
        if self.posterior is False or self.posterior is True:
            return None
        return self.posterior

    def use_forward_model(self, forward: ForwardModel) -> None:
        """Read this episode's estimate through ``forward`` until the next reset (ValueError unless the task's
        estimate reads a forward model and no probe has run)."""
        from plate_env.identify.posterior_state import PosteriorState

        if not self.task.reads_forward_model(self.known_inputs()):
            cal = self.config.calibration is not None
            raise ValueError(f"use_estimate_model: the env's estimate is method {self.config.method!r}"
                             f"{' through a lab calibration' if cal else ''}; a forward "
                             "model is read by method 'atlas' without a calibration only")
        if self.done or self.rows:
            raise ValueError(f"use_estimate_model: call it after reset and before the first probe (the episode has "
                             f"{len(self.rows)} probes{', and has ended' if self.done else ''})")
        self.posterior = PosteriorState(forward)

    def scene(self) -> Scene:
        """What a frame shows (:class:`plate_env.env.render.Scene`): the probes as measured, the current estimate
        (the one the final step's info holds, on the same probes), the truth where the info shows it."""
        est = self.estimate() if self.rows else None
        values = None
        if est is not None and est.ok:
            (lo68, hi68), (lo95, hi95) = est.omega_n_ci68, est.omega_n_ci95
            values = (est.omega_n / math.pi, lo68 / math.pi, hi68 / math.pi, lo95 / math.pi, hi95 / math.pi)
        c, obj = self.config, self.obj
        truth = obj.omega_n / math.pi if obj is not None and (self.done or c.reveal_truth) else None
        return Scene(rows=tuple(self.rows), max_probes=c.max_probes, f_band_hz=c.f_band_hz,
                     omega_n_range_pi=c.omega_n_range_pi, sim_s=self.sim_s, estimate=values,
                     reason=cast(str, est.reason) if est is not None else "no probes", truth_pi=truth,
                     done=self.done and obj is not None)

    def _hidden(self) -> ObjectSpec:
        if self.obj is None:
            raise RuntimeError("call reset() before step() (the episode is over)")
        return self.obj

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["posterior"] = None  # rebuilt from the probes when needed
        return state


def check_action(action: object) -> np.ndarray:
    """The action as 4 floats in [-1, 1], or ValueError naming the bad value. Pure: no state changes, no random
    draw (a vector env checks every sub-env's action with it before any sub-env draws)."""
    try:
        a = np.asarray(action)
        if a.dtype.kind not in "fiu":  # bool, complex, strings, objects: not actions, even if castable
            raise TypeError
        a = a.astype(np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action {action!r} is not an array of 4 real numbers in [-1, 1]") from None
    if a.shape != (4,):
        raise ValueError(f"action must have shape (4,), got {a.shape}: {action!r}")
    values = a.tolist()  # four Python floats: checked without numpy's per-call overhead
    if not all(math.isfinite(x) for x in values):
        raise ValueError(f"action {values} contains NaN or inf; allowed: finite values in [-1, 1]")
    if any(abs(x) > 1.0 + 1e-6 for x in values):
        raise ValueError(f"action {values} is outside the allowed range [-1, 1]")
    return np.asarray(np.clip(a, -1.0, 1.0))


def step_episodes(physics: Physics, steps: Sequence[tuple[EpisodeState, np.random.Generator, object] | None]
                  ) -> list[Step | None]:
    """Step each ``(episode, rng, action)`` of ``steps`` (None: that one does not step): every action checked
    before any random draw (a refusal leaves every episode as it was), then each probe planned (placed from its
    ``rng``), the probes run in one ``physics.run`` call, each result recorded (its camera noise from its ``rng``).
    Per entry the step's ``(obs, reward, terminated, truncated, info)``, or None where it did not step."""
    checked = [None if s is None else s[0].check(s[2]) for s in steps]
    specs: list[ProbeSpec] = []
    plans: list[int | None] = []  # per entry: the index of its probe in specs, or None (a stop, or no step)
    for s, a in zip(steps, checked, strict=True):
        spec = None if s is None or a is None else s[0].plan(a, s[1])
        plans.append(None if spec is None else len(specs))
        if spec is not None:
            specs.append(spec)
    results = physics.run(specs) if specs else []
    return [None if s is None else s[0].finish(None if k is None else results[k], s[1])
            for s, k in zip(steps, plans, strict=True)]
