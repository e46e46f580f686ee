"""Gymnasium environment ``PlateRotation-v0``: probes as actions, identification of omega_n as the goal.

The environment's documentation, in Gymnasium's layout, is :class:`PlateRotationEnv`'s docstring (and the README's
"The environment" section).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from plate_env.core.objects import ObjectSpec
from plate_env.core.probe_table import ProbeTable
from plate_env.core.setup import DEFAULT_MAX_PROBES
from plate_env.env import config as _config
from plate_env.env import info as info_schema
from plate_env.env.codec import ACTION_SIZE, Codec
from plate_env.env.config import RENDER_MODES, ConfigView, EnvConfig, build_physics, forward_name, refuse_unanswerable
from plate_env.env.render import FPS, FRAMES_PER_PROBE, Scene
from plate_env.env.state import EpisodeState, Step, check_action, step_episodes
from plate_env.env.task import RESET_OPTIONS, IdentificationTask
from plate_env.identify.estimate import Estimate
from plate_env.identify.estimators import Estimator
from plate_env.physics.interface import Physics
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.env.render import Renderer
    from plate_env.identify.forward import ForwardModel
    from plate_env.identify.posterior_state import PosteriorState

MASS_KG, OPTION_OF = _config.MASS_KG, _config.OPTION_OF  # where they were
__all__ = ["DEFAULT_MAX_PROBES", "MASS_KG", "OPTION_OF", "RESET_OPTIONS", "EnvConfig", "PlateRotationEnv"]


class PlateRotationEnv(ConfigView, gym.Env[np.ndarray, np.ndarray]):
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
            config = EnvConfig.of(settings)
        elif not isinstance(config, EnvConfig) or settings:
            raise TypeError(f"PlateRotationEnv(config) takes an EnvConfig and no other settings, got {config!r} and "
                            f"{sorted(settings)}")
        #: The env's checked arguments (:class:`~plate_env.env.config.EnvConfig`); ``env.<argument>`` reads them.
        self.config = config
        self._owns_physics = shared_physics is None
        self.physics = build_physics(config) if shared_physics is None else shared_physics
        self.render_mode = config.render_mode
        if config.render_mode == "rgb_array":  # one frame per probe: a probe lasts a second of video in every mode
            self.metadata = {**self.metadata, "render_fps": FPS / FRAMES_PER_PROBE}
        refuse_unanswerable(config, self.physics, config.corner_objects(), "option")
        #: The observation/action layout (plate_env.env.codec), shared with agents that act from observations.
        self.codec = Codec(config.f_band_hz, config.amplitudes_deg, config.measure_range_s, config.max_probes)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(ACTION_SIZE,), dtype=np.float32)
        self.observation_space = spaces.Box(-10.0, 10.0, shape=(self.codec.obs_dim,), dtype=np.float32)
        #: The episode (plate_env.env.state): its probes, its estimate, its step; identification uses the forward
        #: model of the physics the probes come from (the task's).
        self.episode = EpisodeState(config, IdentificationTask(config, forward_name(config, self.physics)),
                                    self.codec)
        if config.render_mode in ("rgb_array_list", "human"):
            self.episode.on_step = self._frame_step
        self._closed = False
        self._renderer: Renderer | None = None  # made on the first frame (only with a render_mode)

    @property
    def task(self) -> IdentificationTask:
        """The identification task (:mod:`plate_env.env.task`): reward, termination, estimator."""
        return self.episode.task

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
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Hide a new object (drawn from the seeded ranges; ``options`` may fix its ``omega_n`` rad/s, ``alpha``
        rad and ``mass`` kg). Unknown option keys, bad values and objects the physics cannot answer are refused."""
        self._check_open()
        given = self.task.reset_values(options)  # refused before the seed or any draw
        super().reset(seed=seed)
        obj = self.task.hidden_object(self.np_random, options)
        if given:
            refuse_unanswerable(self.config, self.physics, [obj], "reset option")
        self.episode.reset(obj)
        if self.render_mode in ("rgb_array_list", "human"):
            self._frames().reset(self._scene())
        return self.episode.observation(), self.episode.info()

    def step(self, action: npt.ArrayLike) -> Step:
        self._check_open()
        out = step_episodes(self.physics, [(self.episode, self.np_random, action)])[0]
        assert out is not None  # an entry that steps has its step
        return out

    def check_action(self, action: npt.ArrayLike) -> np.ndarray:
        """:func:`plate_env.env.state.check_action`: the action as 4 floats in [-1, 1], or ValueError."""
        return check_action(action)

    def encode_action(self, f_p_hz: float | None = None, a_p_deg: float | None = None,
                      measure_s: float | None = None, stop: bool = False) -> np.ndarray:
        """The action that runs a probe at ``f_p_hz`` (Hz), ``a_p_deg`` (one of the amplitudes) and window
        ``measure_s`` (s), or that stops. Values are clipped to the band and window range."""
        if stop:
            return np.array([0.0, 0.0, 0.0, 1.0], dtype=np.float32)
        if f_p_hz is None:
            raise ValueError("encode_action: give the plate frequency f_p_hz (Hz), or stop=True")
        return self.codec.encode(f_p_hz, self.config.amplitudes_deg[0] if a_p_deg is None else a_p_deg,
                                 1.0 if measure_s is None else measure_s)

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this PlateRotationEnv is closed; make a new one")

    # ------------------------------------------------------------------ views
    def table(self) -> ProbeTable:
        """The probes of this episode as the camera measured them."""
        return self.episode.table()

    def estimator(self) -> Estimator:
        """The episode's :class:`~plate_env.identify.estimators.Estimator` (the env's method on the forward model of
        its physics, or its lab calibration), for the episode's known inputs."""
        return self.episode.estimator()

    def estimate(self) -> Estimate:
        """The current omega_n estimate from the probes so far: :meth:`estimator`'s, kept up to date probe by probe
        when it is incremental (the atlas method's :class:`~plate_env.identify.posterior_state.PosteriorState`,
        brought up to date with the probes not in it), else fitted from scratch (the Lorentz method, a lab
        calibration); no estimate with the reason when none can be made."""
        return self.episode.estimate()

    def posterior_state(self) -> PosteriorState | str | None:
        """The episode's incremental posterior (:meth:`estimator`'s ``start()``, probes added by :meth:`estimate`),
        None for an estimator that refits from scratch, or the reason there is none (a str)."""
        return self.episode.posterior_state()

    def use_estimate_model(self, forward: ForwardModel) -> None:
        """Read this episode's estimate -- the one its reward charges -- through ``forward`` (a
        :class:`~plate_env.identify.forward.ForwardModel`, e.g. the one an agent designed its probes on) instead of
        the shipped model of the env's physics, until the next reset. Call it after ``reset`` and before the first
        probe; method ``atlas`` without a lab calibration only (ValueError otherwise). ``run_episode`` calls it with
        the agent's estimate model, so the env's reward and the benchmark's score read one estimate."""
        self._check_open()
        self.episode.use_forward_model(forward)

    def hidden_object(self) -> ObjectSpec | None:
        """The episode's hidden object (None before the first reset), for a scorer or a diagnostic, never for an
        agent: the info shows it on the terminating step only (or on every step with ``reveal_truth=True``)."""
        return self.episode.obj

    def known_inputs(self) -> KnownInputs:
        """What a lab would know of this episode's set-up: B_p and the disc's mass and diameter (weighed and
        measured, unlike its stiffness); the paper's set-up before the first reset."""
        return self.episode.known_inputs()

    # ------------------------------------------------------------------ render / close
    # gymnasium's Env.render declares list[RenderFrame] (RenderFrame: str | ndarray | tuple of arrays), and list is
    # invariant: its stub refuses an override returning list[ndarray] though every ndarray is a RenderFrame
    def render(self) -> np.ndarray | list[np.ndarray] | None:  # type: ignore[override]
        """The frame of the state after the last step (``rgb_array``), the frames collected since the last call
        (``rgb_array_list``: one after reset, ``FRAMES_PER_PROBE`` per probe, ``FPS`` more held at the end), or
        None (``human``: shown as they come; ``render_mode=None``: nothing is drawn)."""
        if self.render_mode is None:
            return None
        return self._frames().render(self._scene())

    def _frames(self) -> Renderer:  # the renderer, made on first use (only with a render_mode)
        if self._renderer is None:
            from plate_env.env.render import Renderer

            assert self.render_mode is not None  # its callers draw nothing without one
            self._renderer = Renderer(self.render_mode)
        return self._renderer

    def _frame_step(self, probed: bool, over: bool) -> None:
        """The frames of a step (``rgb_array_list``, ``human``): the episode state calls it at each step's end."""
        self._frames().step(self._scene(), probed=probed, over=over)

    def _scene(self) -> Scene:
        """What a frame shows (:meth:`plate_env.env.state.EpisodeState.scene`)."""
        return self.episode.scene()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._owns_physics:  # a shared backend is its owner's to close (the vector env's)
            self.physics.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["physics"] = None
        state["_renderer"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.physics = build_physics(self.config)
        self._owns_physics = True  # a copy owns its backend, even of an env that shared one
        self._closed = False


if PlateRotationEnv.__doc__:  # the info table rendered from its one declaration (None under python -OO)
    PlateRotationEnv.__doc__ = PlateRotationEnv.__doc__.replace(
        "{info_table}", "\n".join("    " + line for line in info_schema.markdown("``").splitlines()))
