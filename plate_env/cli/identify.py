"""``plate-env identify``: a probing agent identifies a hidden object (the main job)."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
from typing import TYPE_CHECKING, Any, cast

from plate_env.cli.options import (
    TILELINK_MODELS_HELP,
    CliError,
    add_dt,
    add_object,
    intervals,
    number_arg,
    object_spec,
    physics_options,
    plot_path,
    say_plot,
)
from plate_env.core import checks
from plate_env.core.setup import (
    B_P_RANGE_M,
    DEFAULT_MAX_PROBES,
    MAX_PROBES_RANGE,
    SEED_RANGE,
)
from plate_env.core.streams import stdout_to_stderr
from plate_env.core.units import format_omega_pi
from plate_env.physics import PHYSICS_NAMES

if TYPE_CHECKING:
    import gymnasium as gym

    from plate_env.cli.options import Subparsers
    from plate_env.env.episode import EpisodeResult
    from plate_env.env.protocol import ProbingAgent
    from plate_env.env.rotation import PlateRotationEnv
    from plate_env.identify.forward import ForwardModel


def _agent_names() -> tuple[str, ...]:
    # the seam: the CLI is the application layer, the only module of plate_env that imports the agents
    from plate_env_agents import AGENT_NAMES

    names: tuple[str, ...] = AGENT_NAMES
    return names


def add_parser(sub: Subparsers) -> None:
    """The ``identify`` command on the CLI's subparsers ``sub``."""
    i = sub.add_parser("identify", help="identify a hidden object with a probing agent (the main job)")
    i.add_argument("--agent", default="bayes", choices=_agent_names(), help="the probing agent")
    i.add_argument("--physics", default="tilelink", choices=PHYSICS_NAMES, help="physics backend")
    i.add_argument("--model", default=None, help=f"tilelink model ({TILELINK_MODELS_HELP}; default: pointmass)")
    add_object(i, true="true ")
    i.add_argument("--seed", type=number_arg(checks.integer, *SEED_RANGE), default=0,
                   help="seed of the episode (placement, camera noise)")
    i.add_argument("--bp", type=number_arg(checks.real, B_P_RANGE_M[0] * 1e3, B_P_RANGE_M[1] * 1e3, unit="mm"),
                   default=3.0, help="plate linear amplitude B_p, mm (known input: the physics runs it, the "
                   "forward model is conditioned on it)")
    i.add_argument("--max-probes", type=number_arg(checks.integer, *MAX_PROBES_RANGE), default=DEFAULT_MAX_PROBES,
                   help="probe budget")
    i.add_argument("--target", type=number_arg(checks.real, 0.0, 1.0, open_lo=True, open_hi=True), default=None,
                   help="bayes only: stop at this relative posterior std of omega_n (a fraction; default: none, "
                   "the probe budget alone stops it)")
    add_dt(i)
    i.add_argument("--plot", default=None, help="write a PNG of the probes, fit and estimate (after the results)")
    i.add_argument("--json", action="store_true", help="print one JSON document")


def run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    from plate_env.env.episode import run_episode

    # the seam: the CLI is the application layer, the only module of plate_env that imports the agents
    # (tests/test_code_health.py keeps it so); the library core below it does not
    from plate_env_agents import make_agent

    if args.target is not None and args.agent != "bayes":
        raise CliError(f"--target applies to --agent bayes only (its stopping rule), not to --agent {args.agent}")
    obj = object_spec(args)
    plot = plot_path(args.plot) if args.plot else None
    agent = make_agent(args.agent, **({} if args.target is None else {"target_rel": args.target}))
    env_kw: dict[str, Any] = dict(physics=args.physics, physics_options=physics_options(args),
                                  max_probes=args.max_probes, b_p_mm=args.bp)
    if args.physics == "pybullet":
        env_kw["method"] = "lorentz"
    env = gym.make("PlateRotation-v0", **env_kw)
    plate = cast("PlateRotationEnv", env.unwrapped)

    def show(k: int, p: dict[str, Any]) -> None:
        state = f"unstable: {p['reason']}" if p["unstable"] else f"{p['omega_b_deg_s']:7.1f} deg/s"
        print(f"probe {k:2d}: f_p = {p['f_p_hz']:6.2f} Hz  A_p = {p['a_p_deg']:4.1f} deg  "
              f"{p['sim_s']:.2f} s simulated  -> {state}", flush=True)

    try:
        # with --json, what the agent and the physics print goes to stderr (the text mode shows probes as they end)
        with stdout_to_stderr() if args.json else contextlib.nullcontext():
            res = run_episode(env, agent, seed=args.seed,
                              options={"omega_n": obj.omega_n, "alpha": obj.alpha, "mass": obj.mass},
                              on_probe=None if args.json else show)
        plot_fm = _estimate_forward(env, agent) if plot is not None else None  # the plot's curve at the estimate
    except KeyboardInterrupt:  # the probes so far were shown as they finished; with --json, print them now
        done = plate.table()
        if args.json:
            print(json.dumps({"physics": args.physics, "object": obj.name, "interrupted": True,
                              "probes": done.to_rows()}), flush=True)
        print(f"plate-env identify: interrupted after {len(done)} probes", file=sys.stderr)
        return 130
    finally:
        env.close()
    est = res.estimate
    if args.json:
        print(json.dumps({"physics": args.physics, "object": obj.name, **res.to_dict()}), flush=True)
    else:
        _print_identify(res)
    if plot is not None:
        from plate_env.plotting import plot_fit

        plot_fit(res.probes, est, str(plot), plot_fm, omega_n_true=obj.omega_n)  # the truth printed above
        say_plot(args, plot)
    return 0 if est.ok else 1


def _estimate_forward(env: gym.Env[Any, Any], agent: ProbingAgent) -> ForwardModel | None:
    """The forward model an episode's estimate was computed with (its estimator's,
    :func:`plate_env.env.episode.estimator_of`), or None (the Lorentz method, a lab calibration, a physics without
    one)."""
    from plate_env.env.episode import estimator_of

    forward_model = getattr(estimator_of(env, agent), "forward_model", None)
    try:
        model: ForwardModel | None = None if forward_model is None else forward_model()
    except ValueError:
        return None
    return model


def _print_identify(res: EpisodeResult) -> None:
    est = res.estimate
    if est.ok:
        print(f"omega_n_hat = {est.omega_n:.2f} +- {est.omega_n_stderr:.2f} rad/s ({format_omega_pi(est.omega_n)}) "
              f"by {est.method}")
        print(intervals(est))
        print(f"true        = {res.omega_n_true:.2f} rad/s ({format_omega_pi(res.omega_n_true)});  "
              f"error {100 * res.relative_error:.1f} %")
        if est.alpha is not None:
            print(f"alpha_hat   = {math.degrees(est.alpha):.1f} +- {math.degrees(est.alpha_stderr):.1f} deg "
                  f"(true {math.degrees(res.alpha_true):.1f} deg)")
    else:
        print(f"no estimate: {est.reason}")
    print(f"{res.n_probes} probes, {res.sim_s:.1f} s simulated, {res.wall_s:.1f} s wall", flush=True)
