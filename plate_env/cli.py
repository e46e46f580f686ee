"""``plate-env`` command line: identify, probe, sweep, fit. ``--json`` on every command prints one JSON document."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence

import numpy as np

from plate_env.motion import PlateMotion
from plate_env.objects import ObjectSpec, preset
from plate_env.physics import PHYSICS_NAMES, ProbeSpec, make_physics
from plate_env.units import format_omega_pi, parse_omega_n


class CliError(Exception):
    """A user error: printed as one line, exit code 2."""


def parse_freqs(text: str) -> np.ndarray:
    """``"10:40:1"`` (start:stop:step, inclusive) or ``"12,18,25"`` -> frequencies in Hz."""
    try:
        if ":" in text:
            parts = [float(p) for p in text.split(":")]
            if len(parts) != 3:
                raise ValueError
            start, stop, step = parts
            if not (step > 0 and stop >= start):
                raise ValueError
            freqs = np.arange(start, stop + step * 1e-6, step)
        else:
            freqs = np.array([float(p) for p in text.split(",") if p.strip()])
    except ValueError:
        raise CliError(f"--freqs {text!r}: expected start:stop:step (e.g. 10:40:1) or a list like 12,18,25") from None
    if freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs <= 0) or np.any(freqs > 200):
        raise CliError(f"--freqs {text!r}: frequencies must lie in (0, 200] Hz")
    if freqs.size > 2000:
        raise CliError(f"--freqs {text!r}: {freqs.size} probes; at most 2000 per sweep")
    return freqs


def _object(args: argparse.Namespace) -> ObjectSpec:
    base = preset(args.object) if args.object else ObjectSpec(name="custom")
    changes: dict = {}
    if args.omega_n is not None:
        changes["omega_n"] = parse_omega_n(args.omega_n)
    if args.alpha is not None:
        changes["alpha"] = math.radians(args.alpha)
    if args.mass_g is not None:
        changes["mass"] = args.mass_g * 1e-3
    return base.with_(**changes) if changes else base


def _physics_options(args: argparse.Namespace) -> dict:
    """Backend options from --model and --dt, refused where the backend has no such knob."""
    options: dict = {}
    if args.dt is not None:
        if args.physics == "atlas":
            raise CliError("--dt does not apply to --physics atlas (a tabulated response has no time step)")
        options["dt"] = args.dt
    if args.model:
        if args.physics == "pybullet":
            raise CliError("--model does not apply to --physics pybullet")
        options["model"] = args.model
    return options


def _physics(args: argparse.Namespace):
    return make_physics(args.physics, **_physics_options(args))


def _spec(args: argparse.Namespace, obj: ObjectSpec, freq: float) -> ProbeSpec:
    motion = PlateMotion.from_paper(f_p_hz=freq, a_p_deg=args.amp, b_p_mm=args.bp)
    return ProbeSpec(obj=obj, motion=motion, settle_s=args.settle, measure_s=args.measure)


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--physics", default="tilelink", choices=PHYSICS_NAMES, help="physics backend")
    p.add_argument("--model", default=None, help="tilelink model (pointmass, rigid, rigid_limit); atlas: whose atlas")
    p.add_argument("--object", default=None, help="preset object: cheese, dumpling, cheese_lead")
    p.add_argument("--omega-n", default=None, help="bending natural frequency, rad/s or e.g. 10pi")
    p.add_argument("--alpha", type=float, default=None, help="friction angle, degrees")
    p.add_argument("--mass-g", type=float, default=None, help="object mass, grams")
    p.add_argument("--amp", type=float, default=3.0, help="plate angular amplitude A_p, degrees")
    p.add_argument("--bp", type=float, default=3.0, help="plate linear amplitude B_p, mm")
    p.add_argument("--settle", type=float, default=ProbeSpec.settle_s, help="settling time after the ramp, s")
    p.add_argument("--measure", type=float, default=ProbeSpec.measure_s, help="measurement window, s")
    p.add_argument("--dt", type=float, default=None, help="time step, s (backend default if omitted)")
    p.add_argument("--json", action="store_true", help="print one JSON document")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="plate-env", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("probe", help="run one probe and print omega_B")
    _add_common(p)
    p.add_argument("--freq", type=float, required=True, help="plate frequency f_p, Hz")
    s = sub.add_parser("sweep", help="run a batched frequency sweep")
    _add_common(s)
    s.add_argument("--freqs", default="10:40:1", help="start:stop:step or a comma list, Hz")
    s.add_argument("--plot", default=None, help="write a PNG of omega_B vs f_p")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    i = sub.add_parser("identify", help="identify a hidden object with a probing agent (the main job)")
    i.add_argument("--agent", default="bayes", choices=("grid", "coarse_to_fine", "bayes", "ppo"))
    i.add_argument("--physics", default="tilelink", choices=PHYSICS_NAMES, help="physics backend")
    i.add_argument("--model", default=None, help="tilelink model (pointmass, rigid, rigid_limit)")
    i.add_argument("--object", default=None, help="preset object: cheese, dumpling, cheese_lead")
    i.add_argument("--omega-n", default=None, help="true bending natural frequency, rad/s or e.g. 17pi")
    i.add_argument("--alpha", type=float, default=None, help="true friction angle, degrees")
    i.add_argument("--mass-g", type=float, default=None, help="object mass, grams")
    i.add_argument("--seed", type=int, default=0, help="seed of the episode (placement, camera noise)")
    i.add_argument("--max-probes", type=int, default=30, help="probe budget")
    i.add_argument("--target", type=float, default=None, help="bayes: stop at this relative posterior std")
    i.add_argument("--dt", type=float, default=None, help="time step, s (backend default if omitted)")
    i.add_argument("--plot", default=None, help="write a PNG of the probes, fit and estimate")
    i.add_argument("--json", action="store_true", help="print one JSON document")
    f = sub.add_parser("fit", help="fit a lab sweep (CSV) and estimate omega_n")
    f.add_argument("csv", help="CSV with columns f_p_hz, omega_b_deg_s[, stderr_deg_s, a_p_deg, unstable]")
    f.add_argument("--amp", type=float, default=None, help="plate amplitude A_p of the rows, degrees")
    f.add_argument("--physics", default="tilelink", help="whose calibration/atlas to use (tilelink, paper, ...)")
    f.add_argument("--model", default=None, help="tilelink model of the calibration/atlas (pointmass)")
    f.add_argument("--method", default="lorentz", choices=("lorentz", "atlas"))
    f.add_argument("--plot", default=None, help="write a PNG of data, fitted curve and posterior")
    f.add_argument("--json", action="store_true", help="print one JSON document")
    return parser


def _cmd_probe(args: argparse.Namespace) -> int:
    obj = _object(args)
    physics = _physics(args)
    try:
        result = physics.run([_spec(args, obj, args.freq)])[0]
    finally:
        physics.close()
    if args.json:
        print(json.dumps({"physics": args.physics, "object": obj.name, **result.to_dict()}))
    else:
        state = f"UNSTABLE ({result.reason})" if result.unstable else "stable"
        print(f"{args.physics}: omega_n={format_omega_pi(obj.omega_n)} rad/s alpha={math.degrees(obj.alpha):.1f} deg "
              f"f_p={args.freq:g} Hz A_p={args.amp:g} deg B_p={args.bp:g} mm")
        print(f"omega_B = {result.omega_b_deg_s:.1f} +- {result.stderr_deg_s:.1f} deg/s  [{state}]  "
              f"{result.periods_measured} periods, {result.sim_s:.2f} s simulated in {result.wall_s:.3f} s")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    obj = _object(args)
    freqs = parse_freqs(args.freqs)
    physics = _physics(args)
    try:
        results = physics.run([_spec(args, obj, f) for f in freqs],
                              progress=not (args.json or args.no_progress))
    finally:
        physics.close()
    if args.plot:
        from plate_env.plotting import plot_sweep

        plot_sweep(results, args.plot, title=f"{args.physics}: omega_n={format_omega_pi(obj.omega_n)} rad/s, "
                   f"alpha={math.degrees(obj.alpha):.1f} deg, A_p={args.amp:g} deg")
    if args.json:
        print(json.dumps({"physics": args.physics, "object": obj.name, "probes": [r.to_dict() for r in results]}))
    else:
        print(f"{args.physics}: omega_n={format_omega_pi(obj.omega_n)} rad/s alpha={math.degrees(obj.alpha):.1f} deg "
              f"A_p={args.amp:g} deg B_p={args.bp:g} mm")
        print(f"{'f_p [Hz]':>9} {'omega_B [deg/s]':>16} {'stderr':>8}  state")
        for r in results:
            state = f"unstable: {r.reason}" if r.unstable else "stable"
            print(f"{r.spec.motion.freq_hz:9.2f} {r.omega_b_deg_s:16.1f} {r.stderr_deg_s:8.1f}  {state}")
        print(f"{sum(r.sim_s for r in results):.1f} s simulated in {sum(r.wall_s for r in results):.2f} s wall")
        if args.plot:
            print(f"plot: {args.plot}")
    return 0


def _fit_report(est, table) -> list[str]:
    """An lmfit-like report of the per-amplitude Lorentzian fits."""
    out = []
    for amp, fit in est.fits.items():
        out.append(f"[[Fit A_p = {amp:g} deg]]  (Eq. 9, Levenberg-Marquardt)")
        if not fit.ok:
            out.append(f"    cannot fit: {fit.reason}")
            continue
        out.append(f"    data points = {fit.n_used} used, {fit.n_unstable} unstable excluded")
        out.append(f"    R-squared   = {fit.r2:.4f}")
        for name, val, err, unit in (("omega_max", fit.omega_max, fit.stderr[0], "deg/s"),
                                     ("f0", fit.f0, fit.stderr[1], "Hz"), ("b", fit.b, fit.stderr[2], "Hz")):
            rel = f"({100 * err / abs(val):.2f}%)" if val else ""
            out.append(f"    {name:10s}= {val:10.4g} +/- {err:.4g} {unit} {rel}")
    return out


def _cmd_fit(args: argparse.Namespace) -> int:
    from plate_env.identify import identify
    from plate_env.probes import read_lab_csv

    table = read_lab_csv(args.csv, a_p_deg=args.amp)
    model = args.model or "pointmass"
    est = identify(table, method=args.method, physics=args.physics, model=model)
    if args.plot:
        from plate_env.plotting import plot_fit

        plot_fit(table, est, args.plot)
    if args.json:
        print(json.dumps({"file": str(args.csv), "physics": args.physics, "model": model, **est.to_dict()}))
        return 0 if est.ok else 1
    for line in _fit_report(est, table):
        print(line)
    if est.ok:
        lo, hi = est.omega_n_ci95
        print(f"omega_n_hat = {est.omega_n:.2f} +- {est.omega_n_stderr:.2f} rad/s "
              f"({format_omega_pi(est.omega_n)}; 95 % interval {lo:.1f}-{hi:.1f} rad/s) by {est.method} "
              f"on {args.physics}/{model}")
        if est.alpha is not None:
            print(f"alpha_hat   = {math.degrees(est.alpha):.1f} +- {math.degrees(est.alpha_stderr):.1f} deg")
    else:
        print(f"no estimate: {est.reason}")
    if args.plot:
        print(f"plot: {args.plot}")
    return 0 if est.ok else 1


def _cmd_identify(args: argparse.Namespace) -> int:
    import gymnasium as gym

    # the seam: the CLI is the application layer, the only module of plate_env that imports the agents
    # (tests/test_code_health.py keeps it so); the library core below it does not
    from agents import make_agent
    from agents.runner import run_episode

    obj = _object(args)
    env_kw = dict(physics=args.physics, physics_options=_physics_options(args), max_probes=args.max_probes)
    if args.physics == "pybullet":
        env_kw["method"] = "lorentz"
    env = gym.make("PlateRotation-v0", **env_kw)
    agent_kw = {}
    if args.agent == "bayes" and args.target is not None:
        agent_kw["target_rel"] = args.target
    agent = make_agent(args.agent, **agent_kw)

    def show(k: int, p: dict) -> None:
        state = f"unstable: {p['reason']}" if p["unstable"] else f"{p['omega_b_deg_s']:7.1f} deg/s"
        print(f"probe {k:2d}: f_p = {p['f_p_hz']:6.2f} Hz  A_p = {p['a_p_deg']:4.1f} deg  "
              f"{p['sim_s']:.2f} s simulated  -> {state}", flush=True)

    try:
        res = run_episode(env, agent, seed=args.seed,
                          options={"omega_n": obj.omega_n, "alpha": obj.alpha, "mass": obj.mass},
                          on_probe=None if args.json else show)
    finally:
        env.close()
    if args.plot:
        from plate_env.plotting import plot_fit

        plot_fit(res.probes, res.estimate, args.plot)
    if args.json:
        print(json.dumps({"physics": args.physics, "object": obj.name, **res.to_dict()}))
        return 0 if res.estimate.ok else 1
    est = res.estimate
    if est.ok:
        print(f"omega_n_hat = {est.omega_n:.2f} +- {est.omega_n_stderr:.2f} rad/s ({format_omega_pi(est.omega_n)}) "
              f"by {est.method}")
        print(f"true        = {res.omega_n_true:.2f} rad/s ({format_omega_pi(res.omega_n_true)});  "
              f"error {100 * res.relative_error:.1f} %")
        if est.alpha is not None:
            print(f"alpha_hat   = {math.degrees(est.alpha):.1f} +- {math.degrees(est.alpha_stderr):.1f} deg "
                  f"(true {math.degrees(res.alpha_true):.1f} deg)")
    else:
        print(f"no estimate: {est.reason}")
    print(f"{res.n_probes} probes, {res.sim_s:.1f} s simulated, {res.wall_s:.1f} s wall")
    if args.plot:
        print(f"plot: {args.plot}")
    return 0 if est.ok else 1


COMMANDS = {"probe": _cmd_probe, "sweep": _cmd_sweep, "fit": _cmd_fit, "identify": _cmd_identify}


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except (CliError, ValueError, OSError) as exc:
        print(f"plate-env {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"plate-env {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
