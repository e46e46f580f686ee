"""Gymnasium environment ``PlateRotation-v0``: probes as actions, identification of omega_n as the goal.

The environment's documentation, in Gymnasium's layout, is :class:`PlateRotationEnv`'s docstring (and the README's
"The environment" section).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from plate_env.core import checks, jit
from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectPrior, ObjectSpec
from plate_env.core.probe import (
    ProbeResult,
    ProbeSpec,
)
from plate_env.core.probe_table import ProbeTable
from plate_env.core.setup import DEFAULT_MAX_PROBES
from plate_env.env import info as info_schema
from plate_env.env.codec import ACTION_SIZE, Codec
from plate_env.env.config import ARGUMENTS, MASS_KG, OPTION_OF, RENDER_MODES, EnvConfig, refuse_unanswerable
from plate_env.env.render import FPS, FRAMES_PER_PROBE
from plate_env.env.task import IdentificationTask
from plate_env.identify.estimate import Estimate
from plate_env.identify.estimators import ForwardName, fit_or_refuse
from plate_env.physics import make_physics
from plate_env.physics.camera import camera_omega_b
from plate_env.physics.interface import Physics
from plate_env.surrogate.conditioning import KnownInputs

#: Keys ``reset(options=...)`` accepts: the hidden object's omega_n (rad/s), alpha (rad), mass (kg).
RESET_OPTIONS = ("omega_n", "alpha", "mass")
__all__ = ["DEFAULT_MAX_PROBES", "MASS_KG", "OPTION_OF", "RESET_OPTIONS", "EnvConfig", "PlateRotationEnv"]


class PlateRotationEnv(gym.Env):
    """Identify a hidden object's bending natural frequency by choosing plate probes.

    ## Description

    A thin disc (the paper's cheese slice by default) lies on a plate that rocks about a horizontal axis
    (amplitude A_p) while translating along it (B_p) at a frequency f_p; the disc walks round at a rate omega_B
    that follows its first bending natural frequency omega_n. Each episode hides an object (omega_n, friction
    angle alpha, mass); each step runs one probe of the agent's choosing on the physics backend and a 30 fps
    camera model measures omega_B; the episode ends when the agent stops or the probe budget is spent, and the
    probes are turned into an estimate of omega_n. The reward trades its error against the simulated seconds the
    probes took.

    ## Action Space

    ``Box(-1, 1, (4,), float32)``:

    | index | meaning | mapping |
    |---|---|---|
    | 0 | plate frequency f_p | linearly onto ``f_band_hz`` |
    | 1 | plate amplitude A_p | [-1, 1] split evenly among ``amplitudes_deg`` |
    | 2 | measurement window | linearly onto ``measure_range_s`` |
    | 3 | stop | > 0 ends the episode before this probe runs (ignored on the first step: it runs the probe) |

    Actions outside [-1, 1], NaN, or of another shape are refused (ValueError), never clipped.
    :meth:`encode_action` builds an action from physical values.

    ## Observation Space

    ``Box(-10, 10, (7 * max_probes + 2,), float32)`` (212 with the default ``max_probes`` = 30): one row of 7 per
    probe slot, in the order the probes ran, zeros for slots not yet used:

    | column | meaning |
    |---|---|
    | 0 | f_p, -1..1 over ``f_band_hz`` |
    | 1 | A_p, the amplitude's code (2k + 1) / n - 1 (0 with one amplitude) |
    | 2 | omega_B / 1000, deg/s (0 when the probe ended unstable) |
    | 3 | its standard error / 1000, deg/s |
    | 4 | unstable (1) or stable (0) |
    | 5 | window, -1..1 over ``measure_range_s`` |
    | 6 | filled (1) |

    followed by the share of probes left and the share of ``max_sim_s`` left (1 without a time budget). The
    observation is Markov: it holds every probe so far.

    ## Rewards

    Each probe costs ``cost_per_sim_s`` per simulated second it took (ramp 0.2 s + ``settle_s`` + the window; a
    probe that ends unstable costs the seconds it ran). At the end the estimate omega_n_hat (``method``) is
    scored: ``-min(|omega_n_hat - omega_n| / omega_n, error_cap)``, or ``-no_estimate_penalty`` when no estimate
    can be made (too few usable probes, an answer at the edge of the identifiable range). Defaults: 0.005 per
    simulated second, error cap 1, no-estimate penalty 1.

    ## Starting State

    ``reset`` hides an object drawn from the seeded generator: omega_n log-uniform over ``omega_n_range_pi``
    (units of pi rad/s), alpha uniform over ``alpha_range_deg``, mass 13.6 g times 1 + ``mass_variation`` * U(-1,
    1) (always drawn, in this order, so fixing one by a reset option leaves the others' draws unchanged); no
    probes yet. Each probe places the disc at a random yaw and a 0.2 mm offset from the same generator.

    ## Episode End

    Terminated when the action says stop (after the first probe), when ``max_probes`` probes have run, or when the
    probes have taken ``max_sim_s`` simulated seconds (the probe that crosses it still runs). Never truncated by the
    env itself. An outer ``TimeLimit`` shorter than the episode (``max_episode_steps`` <= ``max_probes``) truncates
    without the env knowing: the truncated step is a non-final one (its reward is that probe's cost, its info has
    no estimate and no truth), so the error is never charged and the return holds the probe costs only. Learners
    that bootstrap truncated steps, as Gymnasium's contract says (SB3 through ``TimeLimit.truncated``), still value
    the error to come; to end episodes with the error charged, bound them with ``max_probes`` or ``max_sim_s``.
    After a truncation ``env.unwrapped.estimate()`` is the estimate of the probes so far (what a stop would have
    charged). The registered ids' TimeLimit is the largest ``max_probes`` accepted: it never cuts an episode short.

    ## Info

    One schema, declared in :mod:`plate_env.env.info` (``FIELDS``): every key below is in every ``info``, of
    ``reset`` and of every ``step``, with the same numpy dtype (float64, int64, bool) or str, so that Gymnasium's
    vector envs, tianshou's ``Batch`` and SB3's ``Monitor(info_keywords=("relative_error",))`` can batch and log it.
    A field without a value holds its empty value (0 for numbers, ``inf`` for ``relative_error``, ``""`` for
    strings; never NaN, which tianshou's trainers refuse in a buffer) and a flag says whether there is one
    (``estimate.ok``, ``estimate.check.ok``, ``last_probe.ok``, ``truth_revealed``). The hidden object (``*_true_*``
    and ``last_probe``'s ``omega_n_rad_s``, ``alpha_deg``, ``mass_g``) is empty until the terminating step, so a policy
    that reads the info learns nothing it could not measure; ``reveal_truth=True`` shows it on every step (for
    diagnostics; never for training). ``last_probe.omega_b_deg_s`` is the observation's omega_B (the camera's
    measurement, 0 for an unstable probe: it has no rotation rate). The estimate's posterior members and
    per-amplitude fits (keys that vary) are not in the info: ``env.unwrapped.estimate()`` has them.

{info_table}

    ## Arguments

    ``gym.make("PlateRotation-v0", **kwargs)``; every argument is checked at construction, once, by
    :class:`~plate_env.env.config.EnvConfig` (ValueError naming it and the allowed values; ``env.config`` holds the
    checked values), and whether the physics can answer every probe the settings allow:

    | argument | default | meaning |
    |---|---|---|
    | ``physics`` | ``"tilelink"`` | ``tilelink`` (the paper's model), ``pybullet``, ``atlas`` (training) |
    | ``physics_options`` | None | the backend's options (below) |
    | ``method`` | ``"atlas"`` | estimate: ``atlas`` (forward-model posterior) or ``lorentz`` (the paper's) |
    | ``omega_n_range_pi`` | (3.5, 33) | hidden omega_n range, pi rad/s |
    | ``alpha_range_deg`` | (30, 60) | hidden friction-angle range, deg |
    | ``mass_variation`` | 0 | relative mass variation around 13.6 g, [0, 1) |
    | ``f_band_hz`` | (10, 40) | plate frequencies the actions span, Hz |
    | ``amplitudes_deg`` | (3, 12) | plate amplitudes the actions choose from, deg |
    | ``b_p_mm`` | 3 | plate translation amplitude B_p, mm |
    | ``max_probes`` | 30 (:data:`DEFAULT_MAX_PROBES`) | probe budget; sets the observation length |
    | ``max_sim_s`` | None | budget in simulated seconds (None: none) |
    | ``measure_range_s`` | (0.25, 2) | measurement windows the actions span, s |
    | ``settle_s`` | 0.5 | settling time after the 0.2 s ramp, s |
    | ``camera_fps`` | 30 | camera frame rate, Hz |
    | ``angle_noise_deg`` | 0.5 | camera angle noise (sd), deg |
    | ``cost_per_sim_s`` | 0.005 | reward cost per simulated second |
    | ``calibration`` | None | a lab calibration (CAL.json, ``"paper"``): the estimate reads the probes through it |
    | ``error_cap`` | 1 | largest error charged |
    | ``no_estimate_penalty`` | 1 | reward when no estimate can be made |
    | ``render_mode`` | None | ``rgb_array`` (a frame per step), ``rgb_array_list`` or ``human`` (a probe
    animated in ``FRAMES_PER_PROBE`` frames); see Rendering |
    | ``reveal_truth`` | False | the hidden object in every step's info (diagnostics only; see Info) |

    ``physics_options``: e.g. ``{"model": "rigid"}`` or ``{"dt": 2e-4}`` for tilelink; for the atlas
    ``{"instability_rho": 0.9, "instability_corr_hz": 2.0}`` draws instability correlated along f_p within an
    object, as live probes are (the shipped policy's training setting).

    ## Reset Options

    ``reset(seed=..., options={...})`` with keys ``omega_n`` (rad/s), ``alpha`` (rad), ``mass`` (kg) fixes the hidden
    object (the other quantities are still drawn). Unknown keys, non-numbers and objects the physics cannot answer
    are refused (ValueError naming the option).

    ## Rendering

    ``render_mode="rgb_array"``: :meth:`render` draws the state after the last step, one frame per probe
    (``metadata["render_fps"]`` 1 on such an env: Gymnasium's ``RecordVideo`` gives a second per probe).
    ``"rgb_array_list"`` (the video) and ``"human"`` (a window): each probe played in ``FRAMES_PER_PROBE`` frames
    at ``render_fps`` (a second a probe) from its motion and measured omega_B, not re-simulated, plus a second at the
    end. Each frame shows the probe (f_p, A_p, window, omega_B or UNSTABLE), the disc's yaw and trail, the plate's
    tilt with the disc on it, the probes' omega_B(f_p), the current estimate with its intervals and, where the info
    shows it, the truth (:mod:`plate_env.env.render`). Without a render mode nothing is drawn or estimated for it.

    ## Vector Environments

    ``gym.make_vec("PlateRotation-v0", num_envs=8, vectorization_mode="vector_entry_point", physics="atlas")``:
    one batched physics call per step for all sub-environments (Gymnasium's next-step autoreset);
    ``plate_env.env.sb3.make_sb3_vec_env(n_envs=8, physics="atlas")``: the same as a Stable-Baselines3 ``VecEnv``.

    ## Version History

    * v0 (plate-env 0.1.0, unreleased): this definition. Before the first release v0 changed in place; changes
      that alter results of code written against earlier commits: the default ``max_probes`` 20 -> 30 (one default
      everywhere; the observation grew from 142 to 212), the estimate from forward models with the known inputs
      B_p, mass and diameter (issue 13), every argument and reset option checked (issue 16). From the first
      release on, a change that alters observations, rewards or episodes for the same arguments gets a new id
      (``PlateRotation-v1``), as the benchmark's suites do.
    * v1 (``PlateRotation-v1`` live, ``PlateRotationAtlas-v1`` from the atlas; issue 33): the same contract with the
      physics the project's own studies show reproduces the paper as default, the rigid tile-link disc
      (``physics_options={"model": "rigid_fast"}``) instead of the point mass, at the amplitudes its atlas answers,
      ``amplitudes_deg=(3.0, 6.0)`` (12 deg folds soft discs); the estimate reads the forward model
      ``tilelink/rigid_fast``. v0 and its numbers are unchanged. Any argument overrides these defaults.

    ## Ids: training and evaluation

    ``PlateRotation-v0`` and ``PlateRotation-v1`` run live physics (evaluation: milliseconds to seconds a probe);
    train on their atlas twins, ``PlateRotationAtlas-v0`` (the point mass's atlas, ``physics="atlas"``) and
    ``PlateRotationAtlas-v1`` (the rigid tiles' atlas), which answer the same probes in microseconds. A client that
    takes only an id (CleanRL's ``--env-id``, rl-zoo3 without a conf file, torchrl) should be given an atlas id for
    training (``experiments/results/env_ids_speed.md``: steps per second of each).
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": FPS}

    def __init__(self, config: EnvConfig | None = None, shared_physics: Physics | None = None,
                 **settings: Any) -> None:
        """``PlateRotationEnv(**settings)`` (what ``gym.make`` calls: the arguments above, checked by
        :class:`~plate_env.env.config.EnvConfig`), or ``PlateRotationEnv(config)`` from a checked config.
        ``shared_physics``: a backend built for ``config`` by its owner (the vector env's, shared by its
        sub-environments), which this env runs but never closes; None: the env builds and owns its own."""
        super().__init__()
        if config is None:
            unknown = sorted(set(settings) - set(ARGUMENTS))
            if unknown:
                raise TypeError(f"PlateRotationEnv got an unexpected keyword argument {unknown[0]!r}; its arguments: "
                                f"{', '.join(ARGUMENTS)}")
            config = EnvConfig(**settings)
        elif not isinstance(config, EnvConfig) or settings:
            raise TypeError(f"PlateRotationEnv(config) takes an EnvConfig and no other settings, got {config!r} and "
                            f"{sorted(settings)}")
        #: The env's checked arguments (:class:`~plate_env.env.config.EnvConfig`); ``env.<argument>`` reads them.
        self.config = config
        self._owns_physics = shared_physics is None
        self.physics = _build_physics(config.physics, config.options()) if shared_physics is None else shared_physics
        # identification uses the calibration/atlas of the physics the probes come from
        #: The identification task: reward, termination and estimate (plate_env.env.task).
        self.task = IdentificationTask(config, ForwardName(getattr(self.physics, "source", config.physics),
                                                           getattr(self.physics, "model", config.physics)))
        self.render_mode = config.render_mode
        if config.render_mode == "rgb_array":  # one frame per probe: a probe lasts a second of video in every mode
            self.metadata = {**self.metadata, "render_fps": FPS / FRAMES_PER_PROBE}
        refuse_unanswerable(config, self.physics, config.corner_objects(), "option")
        #: The observation/action layout (plate_env.env.codec), shared with agents that act from observations.
        self.codec = Codec(self.f_band_hz, self.amplitudes_deg, self.measure_range_s, self.max_probes)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(ACTION_SIZE,), dtype=np.float32)
        self.observation_space = spaces.Box(-10.0, 10.0, shape=(self.codec.obs_dim,), dtype=np.float32)
        self._obj: ObjectSpec | None = None
        self._rows: list[tuple[float, float, float, float, bool, float]] = []
        self._results: list[ProbeResult] = []
        self._sim_s = 0.0
        self._wall_s = 0.0
        self._done = True
        self._last: ProbeResult | None = None
        self._closed = False
        self._renderer = None  # plate_env.env.render.Renderer, made on the first frame (never without render_mode)
        self._posterior = None  # the episode's PosteriorState, False (not incremental) or why none; built lazily
        self._obs_rows = np.zeros(self.codec.obs_dim, dtype=np.float32)  # the probes' rows, each written once

    def __getattr__(self, name: str) -> Any:
        """``env.<argument>``: the checked value of a constructor argument (``env.max_probes``, ``env.calibration``:
        the loaded lab calibration)."""
        config = self.__dict__.get("config")
        if config is not None and name in ARGUMENTS and name != "physics":
            return getattr(config, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def source(self) -> str:
        """The physics whose forward model and Eq. (10) lines read the probes (``physics/model``'s first part)."""
        return self.task.forward.physics

    @property
    def model(self) -> str:
        """The model of :attr:`source` that made the probes' data (``physics/model``'s second part)."""
        return self.task.forward.model

    @property
    def physics_name(self) -> str:
        """The backend's name (the ``physics`` argument; ``env.physics`` is the backend)."""
        return self.config.physics

    @property
    def physics_options(self) -> dict[str, Any]:
        """The backend's options (the ``physics_options`` argument; empty for none)."""
        return self.config.options()

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Hide a new object (drawn from the seeded ranges; ``options`` may fix its ``omega_n`` rad/s, ``alpha``
        rad and ``mass`` kg). Unknown option keys, bad values and objects the physics cannot answer are refused."""
        self._check_open()
        options = checks.known_keys("reset options", options, RESET_OPTIONS)
        given = {k: checks.real(f"reset option {k}", v) for k, v in options.items()}
        super().reset(seed=seed)
        rng = self.np_random
        drawn_omega, drawn_alpha = ObjectPrior(self.omega_n_range_pi, self.alpha_range_deg).draw(rng)
        drawn = {"omega_n": drawn_omega, "alpha": drawn_alpha,
                 "mass": MASS_KG * (1.0 + self.mass_variation * rng.uniform(-1.0, 1.0))}  # drawn either way
        try:
            obj = ObjectSpec(**{**drawn, **given}, name="hidden")
        except ValueError as exc:
            raise ValueError(f"reset options {options!r}: {exc}") from None
        if given:
            refuse_unanswerable(self.config, self.physics, [obj], "reset option")
        self._obj = obj
        self._rows, self._results = [], []
        self._obs_rows = np.zeros(self.codec.obs_dim, dtype=np.float32)
        self._sim_s = self._wall_s = 0.0
        self._done = False
        self._last = None
        self._posterior = None
        if self.render_mode in ("rgb_array_list", "human"):
            self._frames().reset(self._scene())
        return self._obs(), self._info()

    def decode_action(self, action) -> tuple[bool, ProbeSpec | None]:
        """Check an action and turn it into (stop, probe). Raises ValueError naming a bad value (before any random
        draw: the placement of the probe is drawn only for a valid action)."""
        return self._decode(self.check_action(action))

    def _decode(self, a: np.ndarray) -> tuple[bool, ProbeSpec | None]:
        """:meth:`decode_action` of an action :meth:`check_action` returned."""
        if a[3] > 0 and self._rows:
            return True, None
        f, a_p, window = self.codec.decode(a)
        motion = PlateMotion.from_paper(f, a_p, self.b_p_mm)
        spec = ProbeSpec(self._obj, motion, settle_s=self.settle_s, measure_s=window, record_trace=True)
        return False, spec.perturbed(self.np_random)

    def check_action(self, action) -> np.ndarray:
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
        return np.clip(a, -1.0, 1.0)

    def encode_action(self, f_p_hz: float | None = None, a_p_deg: float | None = None,
                      measure_s: float | None = None, stop: bool = False) -> np.ndarray:
        """The action that runs a probe at ``f_p_hz`` (Hz), ``a_p_deg`` (one of the amplitudes) and window
        ``measure_s`` (s), or that stops. Values are clipped to the band and window range."""
        if stop:
            return np.array([0.0, 0.0, 0.0, 1.0], dtype=np.float32)
        return self.codec.encode(f_p_hz, self.amplitudes_deg[0] if a_p_deg is None else a_p_deg,
                                 1.0 if measure_s is None else measure_s)

    def step(self, action):
        stop, spec = self.prepare(action)
        result = None if stop else self.physics.run([spec])[0]
        return self.finish(result)

    def prepare(self, action) -> tuple[bool, ProbeSpec | None]:
        """First half of a step: validate the action, decide stop or the probe to run (for batched vector envs)."""
        return self._decode(self.check_step(action))

    def check_step(self, action) -> np.ndarray:
        """Refuse a step before anything happens: a closed env, an episode not reset or over, a bad action; the
        checked action (:meth:`check_action`) otherwise."""
        self._check_open()
        if self._obj is None or self._done:
            raise RuntimeError("call reset() before step() (the episode is over)")
        return self.check_action(action)

    def finish(self, result: ProbeResult | None):
        """Second half of a step: record the probe (or stop), compute reward, termination and info."""
        reward = 0.0
        if result is not None:
            omega, se = camera_omega_b(result, self.np_random, self.camera_fps, self.angle_noise_deg)
            if result.unstable:
                omega, se = 0.0, 0.0
            spec = result.spec
            self._rows.append((spec.motion.freq_hz, spec.motion.a_p_deg, omega, se, result.unstable, spec.measure_s))
            k = len(self._rows) - 1
            if k < self.max_probes:  # the observation's row of this probe, written once
                self.codec.put_row(self._obs_rows, k, self._rows[k])
            self._results.append(result)
            self._sim_s += result.sim_s
            self._wall_s += result.wall_s
            self._last = result
            reward -= self.task.probe_cost(result.sim_s)
        terminated = result is None or self.task.budget_spent(len(self._rows), self._sim_s)
        if terminated:
            self._done = True
            est = self.estimate()
            charge, error = self.task.charge(est, self._obj.omega_n)
            reward -= charge
            info = self._info(final=True, estimate=est, error=error)
            jit.episode_ended()  # a process that runs many episodes loads the compiled kernels (plate_env.core.jit)
        else:
            info = self._info()
        if self.render_mode in ("rgb_array_list", "human"):
            self._frames().step(self._scene(), probed=result is not None, over=terminated)
        return self._obs(), float(reward), bool(terminated), False, info

    # ------------------------------------------------------------------ checks
    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this PlateRotationEnv is closed; make a new one")

    # ------------------------------------------------------------------ views
    def table(self) -> ProbeTable:
        """The probes of this episode as the camera measured them."""
        if not self._rows:
            return ProbeTable.from_arrays([], [], [])
        f, a, w, se, un, _ = zip(*self._rows, strict=True)
        return ProbeTable.from_arrays(f, a, w, se, un)

    def estimator(self):
        """The episode's :class:`~plate_env.identify.estimators.Estimator` (the env's method on the forward model of
        its physics, or its lab calibration), for the episode's known inputs."""
        return self.task.estimator(self.known_inputs())

    def estimate(self) -> Estimate:
        """The current omega_n estimate from the probes so far: :meth:`estimator`'s, kept up to date probe by probe
        when it is incremental (the atlas method's :class:`~plate_env.identify.posterior_state.PosteriorState`,
        brought up to date with the probes not in it), else fitted from scratch (the Lorentz method, a lab
        calibration); no estimate with the reason when none can be made."""
        if not self._rows:
            return self.task.no_estimate("no probes")
        state = self.posterior_state()
        if isinstance(state, str):
            return self.task.no_estimate(state)
        if state is None:
            return fit_or_refuse(self.estimator(), self.table())
        if state.n_probes < len(self._rows):
            state.add_table(self.table(), start=state.n_probes)
        return state.estimate()

    def posterior_state(self):
        """The episode's incremental posterior (:meth:`estimator`'s ``start()``: a
        :class:`~plate_env.identify.posterior_state.PosteriorState` conditioned on the episode's known inputs, probes
        added by :meth:`estimate`), None for an estimator that refits from scratch, or the reason there is none (a
        str)."""
        if self._posterior is None:
            self._posterior = self.task.start(self.known_inputs())
        return None if self._posterior is False else self._posterior

    def use_estimate_model(self, forward) -> None:
        """Read this episode's estimate -- the one its reward charges -- through ``forward`` (a
        :class:`~plate_env.identify.forward.ForwardModel`, e.g. the one an agent designed its probes on) instead of
        the shipped model of the env's physics, until the next reset. Call it after ``reset`` and before the first
        probe; method ``atlas`` without a lab calibration only (ValueError otherwise). ``run_episode`` calls it with
        the agent's estimate model, so the env's reward and the benchmark's score read one estimate."""
        from plate_env.identify.posterior_state import PosteriorState

        self._check_open()
        if not self.task.reads_forward_model(self.known_inputs()):
            raise ValueError(f"use_estimate_model: the env's estimate is method {self.method!r}"
                             f"{' through a lab calibration' if self.calibration is not None else ''}; a forward "
                             "model is read by method 'atlas' without a calibration only")
        if self._done or self._rows:
            raise ValueError(f"use_estimate_model: call it after reset and before the first probe (the episode has "
                             f"{len(self._rows)} probes{', and has ended' if self._done else ''})")
        self._posterior = PosteriorState(forward)

    def hidden_object(self) -> ObjectSpec | None:
        """The episode's hidden object (None before the first reset), for a scorer or a diagnostic, never for an
        agent: the info shows it on the terminating step only (or on every step with ``reveal_truth=True``)."""
        return self._obj

    def known_inputs(self) -> KnownInputs:
        """What a lab would know of this episode's set-up: B_p and the disc's mass and diameter (weighed and
        measured, unlike its stiffness); the paper's set-up before the first reset."""
        if self._obj is None:
            return KnownInputs(b_p=self.b_p_mm * 1e-3)
        return KnownInputs(b_p=self.b_p_mm * 1e-3, mass=self._obj.mass, diameter=self._obj.diameter)

    def _obs(self) -> np.ndarray:
        """``Codec.observation`` of the probes so far, from the rows written as each probe arrived."""
        sim_left = 1.0 - self._sim_s / self.max_sim_s if self.max_sim_s else 1.0
        return self.codec.completed(self._obs_rows, 1.0 - len(self._rows) / self.max_probes, sim_left)

    def _info(self, final: bool = False, estimate: Estimate | None = None, error: float | None = None) -> dict:
        """The step's info (:mod:`plate_env.env.info`: every key on every step): the hidden object on the
        terminating step (``final``) or with ``reveal_truth``, the estimate and its error on the terminating step."""
        truth = (final or self.reveal_truth) and self._obj is not None
        v: dict[str, Any] = {"truth_revealed": truth, "probes": len(self._rows), "sim_s": self._sim_s,
                             "estimate.ok": False, "estimate.check.ok": False, "last_probe.ok": self._last is not None}
        if truth:
            v.update(omega_n_true_rad_s=self._obj.omega_n, alpha_true_rad=self._obj.alpha, mass_true_kg=self._obj.mass)
        if self._last is not None:
            p = self._last.to_dict()
            _, _, omega, se, unstable, _ = self._rows[-1]  # the camera's measurement: the observation's and the table's
            v.update({"last_probe.f_p_hz": p["f_p_hz"], "last_probe.a_p_deg": p["a_p_deg"],
                      "last_probe.b_p_mm": p["b_p_mm"], "last_probe.omega_b_deg_s": omega,
                      "last_probe.stderr_deg_s": se, "last_probe.unstable": unstable,
                      "last_probe.reason": p["reason"], "last_probe.sim_s": p["sim_s"],
                      "last_probe.periods_measured": p["periods_measured"]})
            if truth:
                v.update({"last_probe.omega_n_rad_s": p["omega_n_rad_s"], "last_probe.alpha_deg": p["alpha_deg"],
                          "last_probe.mass_g": p["mass_g"]})
        if final:
            v["wall_s"] = self._wall_s
            v["relative_error"] = error
            if estimate is not None:
                v.update(_estimate_values(estimate))
        return info_schema.build(v)

    # ------------------------------------------------------------------ render / close
    def render(self):
        """The frame of the state after the last step (``rgb_array``), the frames collected since the last call
        (``rgb_array_list``: one after reset, ``FRAMES_PER_PROBE`` per probe, ``FPS`` more held at the end), or
        None (``human``: shown as they come; ``render_mode=None``: nothing is drawn)."""
        if self.render_mode is None:
            return None
        return self._frames().render(self._scene())

    def _frames(self):
        """The renderer (:class:`plate_env.env.render.Renderer`), made on first use."""
        if self._renderer is None:
            from plate_env.env.render import Renderer

            self._renderer = Renderer(self.render_mode)
        return self._renderer

    def _scene(self):
        """What a frame shows (:class:`plate_env.env.render.Scene`): the probes as measured, the current estimate
        (the one the final step's info holds, on the same probes), the truth where the info shows it."""
        from plate_env.env.render import Scene

        est = self.estimate() if self._rows else None
        values = None
        if est is not None and est.ok:
            values = tuple(x / math.pi for x in (est.omega_n, *est.omega_n_ci68, *est.omega_n_ci95))
        truth = self._obj.omega_n / math.pi if self._obj is not None and (self._done or self.reveal_truth) else None
        return Scene(rows=tuple(self._rows), max_probes=self.max_probes, f_band_hz=self.f_band_hz,
                     omega_n_range_pi=self.omega_n_range_pi, sim_s=self._sim_s, estimate=values,
                     reason=est.reason if est is not None else "no probes", truth_pi=truth,
                     done=self._done and self._obj is not None)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._owns_physics:  # a shared backend is its owner's to close (the vector env's)
            self.physics.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["physics"] = None
        state["_renderer"] = None
        state["_posterior"] = None  # rebuilt from the probes when needed
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.physics = make_physics(self.physics_name, **self.physics_options)
        self._owns_physics = True  # a copy owns its backend, even of an env that shared one
        self._closed = False


if PlateRotationEnv.__doc__:  # the info table rendered from its one declaration (None under python -OO)
    PlateRotationEnv.__doc__ = PlateRotationEnv.__doc__.replace(
        "{info_table}", "\n".join("    " + line for line in info_schema.markdown("``").splitlines()))


def _estimate_values(est: Estimate) -> dict[str, Any]:
    """The info fields (dotted keys, :mod:`plate_env.env.info`) of an estimate: ``Estimate.to_dict`` with its
    intervals split into their ends, its bound and check in fixed fields, and without the fields whose keys vary
    (the posterior's members, the per-amplitude fits: ``env.unwrapped.estimate()`` has them)."""
    d = est.to_dict()
    v = {f"estimate.{k}": d[k] for k in ("ok", "method", "reason", "forward", "n_probes", "n_unstable")}
    if est.omega_n > 0:  # an answer (a rejected one, ok False, keeps its values); 0: none, empty in the info
        v.update({f"estimate.{k}": d[k] for k in ("omega_n_rad_s", "omega_n_stderr_rad_s", "omega_n_pi")})
        for level in ("68", "95"):
            v[f"estimate.omega_n_ci{level}_lo_rad_s"], v[f"estimate.omega_n_ci{level}_hi_rad_s"] = \
                d[f"omega_n_ci{level}_rad_s"]
    if est.alpha is not None:
        v["estimate.alpha_deg"], v["estimate.alpha_stderr_deg"] = d["alpha_deg"], d["alpha_stderr_deg"]
    if d["bound"] is not None:
        v["estimate.bound.side"], v["estimate.bound.omega_n_rad_s"] = d["bound"]["side"], d["bound"]["omega_n_rad_s"]
    check = d["check"]
    if check is not None:
        v["estimate.check.ok"] = True
        v.update({f"estimate.check.{k}": check[k] for k in ("passed", "statistic", "p_value", "p_min", "n_probes",
                                                            "member")})
        if check["worst"] is not None:
            v.update({f"estimate.check.worst.{k}": x for k, x in check["worst"].items()})
    return v


def _build_physics(name: str, options: dict):
    """``make_physics(name, **options)``, an option the backend does not take or refuses named as a
    ``physics_options`` error."""
    try:
        return make_physics(name, **options)
    except TypeError as exc:  # an unknown keyword
        raise ValueError(f"physics_options {options!r}: physics {name!r} does not take that option ({exc})") from None
    except ValueError as exc:
        raise ValueError(f"physics_options {options!r} for physics {name!r}: {exc}") from None
