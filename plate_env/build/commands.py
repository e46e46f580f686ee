"""``plate-env build suite|atlas|forward-models|calibration|design-discrepancy|pybullet-table|policy``: rebuild a
shipped artifact from the installed package. Every artifact written records the command, the package version and the
git commit (:mod:`plate_env.build.provenance`). ``policy`` trains with the agents' package (``plate_env_agents.train``),
which only the command line may import: :mod:`plate_env.cli` runs it."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from plate_env.run.executor import add_executor_argument

#: What ``plate-env build`` can rebuild.
ARTIFACTS = ("suite", "atlas", "forward-models", "calibration", "design-discrepancy", "pybullet-table", "policy")


def add_build_parser(sub) -> None:
    """The ``build`` command and its artifacts on the CLI's subparsers ``sub``."""
    b = sub.add_parser("build", help="rebuild a shipped artifact (suite, atlas, forward-models, calibration, "
                       "design-discrepancy, pybullet-table, policy) from the installed package")
    kinds = b.add_subparsers(dest="artifact", required=True)
    s = kinds.add_parser("suite", help="write an evaluation suite exactly as shipped (plate_env/data/suites)")
    s.add_argument("name", help="the suite (atlas-v0, tilelink-v0, pybullet-v0, faithful-v0)")
    s.add_argument("--out", required=True, help="the suite file to write; the build record goes to "
                   "OUT.provenance.json")
    a = kinds.add_parser("atlas", help="probe a physics backend over a grid and write its response atlas (.npz)")
    a.add_argument("--physics", default="tilelink", help="tilelink or pybullet")
    a.add_argument("--model", default="pointmass", help="tile-link model (pointmass, rigid, rigid_limit, ...)")
    a.add_argument("--grid", default=None, help="a named grid (tilelink, pybullet), a shipped grid "
                   "(plate_env/data/grids: pointmass_m13.6 is the shipped tilelink/pointmass atlas's) or a grid "
                   ".json file (default: pybullet for --physics pybullet, else tilelink)")
    a.add_argument("--repeats", type=int, default=3, help="placed repeats per grid node")
    a.add_argument("--seed", type=int, default=0, help="seed of the placements (and of the held-out points)")
    a.add_argument("--held-out", type=int, default=None, help="live probes at held-out points that score the atlas "
                   "and fit its sigma_model (default 120; 0 for pybullet)")
    a.add_argument("--select", action="append", default=[], metavar="AXIS=V1,V2",
                   help="build only the grid nodes with these values on an axis (f_p_hz, a_p_deg, omega_n_pi, "
                   "alpha_deg; repeatable), each placed as in the whole grid's build")
    a.add_argument("--nuisance", default=None, help="tile-link joint/contact values, e.g. "
                   "'zeta_bending=0.05,k_inplane=1000' (plate_env.physics.nuisance.Nuisance fields)")
    a.add_argument("--backend-option", action="append", default=[], metavar="KEY=VALUE",
                   help="a backend option, e.g. n_layer=150 or dt=4e-4 for pybullet (repeatable)")
    add_executor_argument(a)
    a.add_argument("--chunk", type=int, default=None, help="probes per chunk (default: a sweep for pybullet, 128 "
                   "in-process, 16 on workers)")
    a.add_argument("--name", default=None, help="file the cache (and default output) as atlas_NAME")
    a.add_argument("--out", default=None, help="the atlas to write (default atlas_<physics>_<model>.npz, or "
                   "atlas_NAME.npz, here)")
    a.add_argument("--cache-dir", default=".", help="finished chunks are appended to CACHE_DIR/atlas_<name>.jsonl; "
                   "re-running resumes from it")
    a.add_argument("--report", default=None, help="also write the build's markdown report here")
    a.add_argument("--no-progress", action="store_true", help="no progress bar (outside a terminal: a few plain "
                   "lines)")
    f = kinds.add_parser("forward-models", help="write the forward-model registry (plate_env/data/forward_models.json) "
                         "from the measured numbers of experiments/forward_models.py's within and lomo stages")
    f.add_argument("--within", default=None, help="the within stage's numbers (default: the frozen input "
                   "plate_env/data/inputs/forward_models_within.json)")
    f.add_argument("--lomo", default=None, help="the lomo stage's numbers (default: the frozen input "
                   "plate_env/data/inputs/forward_models_lomo.json)")
    f.add_argument("--faithful", default=None, help="the faithful forward model's numbers (default: the frozen "
                   "input plate_env/data/inputs/faithful_forward.json)")
    f.add_argument("--out", required=True, help="the registry to write; the build record goes to "
                   "OUT.provenance.json")
    c = kinds.add_parser("calibration", help="write a shipped calibration: paper (plate_env/data/"
                         "calibration_paper.json, --calibration paper) from the paper's published numbers; eq10 "
                         "(plate_env/data/calibration.json, fit --method lorentz) from sweeps")
    c.add_argument("name", help="the calibration (paper, eq10)")
    c.add_argument("--out", required=True, help="the calibration to write; the build record goes to "
                   "OUT.provenance.json")
    c.add_argument("--sweeps", default=None, help="eq10: where the simulated sweeps are cached, resumable (the "
                   "tile-link lines' 2,232 probes and the lab line's 3,720 point-mass probes, about 2 minutes here; "
                   "default: the user cache directory's sweeps/)")
    c.add_argument("--lab-sweeps", default=None, help="eq10: the directory holding the lab line's "
                   "rigid-limit and PyBullet sweeps (eval_tilelink_rigid_limit_A3_s100.jsonl, "
                   "eval_pybullet_pybullet_A3_s600.jsonl) and the rigid_fast line's (the faithful atlas's probes, "
                   "atlas_faithful.jsonl); default: the frozen inputs, plate_env/data/inputs. "
                   "They are inputs, never simulated by the builder: a quarter of an hour to hours of simulation "
                   "here, and their last bits depend on the CPU")
    add_executor_argument(c)
    c.add_argument("--no-progress", action="store_true", help="eq10: no progress bar (outside a terminal: a few "
                   "plain lines)")
    d = kinds.add_parser("design-discrepancy", help="write the bayes agent's design discrepancy "
                         "(plate_env_agents/models/bayes_design_discrepancy.json) from the fit of "
                         "experiments/forward_models.py's within stage")
    d.add_argument("--within", default=None, help="the within stage's numbers (default: the frozen input "
                   "plate_env/data/inputs/forward_models_within.json)")
    d.add_argument("--out", required=True, help="the file to write; the build record goes to OUT.provenance.json")
    t = kinds.add_parser("pybullet-table", help="measure the PyBullet sheet's stiffness -> omega_n table "
                         "(plate_env/data/pybullet_calibration.json): 11 ring-downs of the default sheet, about "
                         "20 s of PyBullet here")
    t.add_argument("--out", required=True, help="the table to write; the build record (with the machine) goes to "
                   "OUT.provenance.json")
    add_policy_parser(kinds)


def add_policy_parser(kinds) -> None:
    """``plate-env build policy``: train a PPO policy from the hyperparameters installed with the agents."""
    p = kinds.add_parser("policy", help="train the shipped PPO policy (plate_env_agents/models/ppo_plate.zip) from "
                         "the hyperparameters installed with the package (plate_env_agents/hyperparams/ppo.yml)")
    p.add_argument("--out", required=True, help="the model zip to write; its numpy export goes to OUT.npz and its "
                   "metadata (command, version, commit, seed, hyperparameters, evaluation curve) to OUT.json")
    p.add_argument("--seed", type=int, default=0, help="seed of the training envs, the policy and SB3")
    p.add_argument("--env-id", default="PlateRotation-v0", help="the hyperparameter file's entry to train (its "
                   "env_kwargs): PlateRotation-v0 (the point-mass atlas, the shipped policy) or PlateRotationAtlas-v1 "
                   "(the faithful rigid tiles' atlas)")
    p.add_argument("--timesteps", type=int, default=None, help="steps to train (default: the file's n_timesteps; "
                   "SB3 finishes the rollout it is in, so a multiple of n_steps * n_envs runs)")
    p.add_argument("--hyperparams", default=None, help="an rl-zoo3 hyperparameter file (default: the installed "
                   "plate_env_agents/hyperparams/ppo.yml)")
    p.add_argument("--eval-freq", type=int, default=8192, help="score the deterministic policy every this many "
                   "steps (all envs) and keep the best model; 0: no evaluation, keep the last model")
    p.add_argument("--eval-episodes", type=int, default=100, help="episodes per evaluation")
    p.add_argument("--eval-seed", type=int, default=10_000, help="seed of the evaluation objects (the same at "
                   "every evaluation)")
    p.add_argument("--threads", type=int, default=1, help="torch threads")


def _pairs(values: Sequence[str], what: str) -> dict[str, str]:
    out = {}
    for kv in values:
        key, sep, value = kv.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise ValueError(f"{what} {kv!r}: expected KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def _number(text: str, what: str) -> float:
    try:
        return int(text) if text.lstrip("-").isdigit() else float(text)
    except ValueError:
        raise ValueError(f"{what}: {text!r} is not a number") from None


def atlas_job(args: argparse.Namespace, record: dict):
    """The :class:`~plate_env.build.atlas.AtlasJob` of ``plate-env build atlas``'s arguments (checked first)."""
    from plate_env.build.atlas import AtlasJob, resolve_grid
    from plate_env.physics.nuisance import Nuisance

    if args.repeats < 1:
        raise ValueError(f"--repeats {args.repeats}: needs at least 1")
    if args.held_out is not None and args.held_out < 0:
        raise ValueError(f"--held-out {args.held_out}: needs 0 or more")
    if args.chunk is not None and args.chunk < 1:
        raise ValueError(f"--chunk {args.chunk}: needs at least 1")
    nuisance = None
    if args.nuisance:
        try:
            nuisance = Nuisance(**{k: float(v) for k, v in _pairs(args.nuisance.split(","), "--nuisance").items()})
        except TypeError as exc:
            raise ValueError(f"--nuisance {args.nuisance!r}: {exc}") from None
    options = {k: _number(v, f"--backend-option {k}")
               for k, v in _pairs(args.backend_option, "--backend-option").items()}
    select = {k: tuple(_number(x, f"--select {k}") for x in v.split(","))
              for k, v in _pairs(args.select, "--select").items()}
    job = AtlasJob(physics=args.physics, model=args.model, grid_name=args.grid, repeats=args.repeats, seed=args.seed,
                   held_out=args.held_out, nuisance=nuisance, options=options, executor=args.executor,
                   chunk=args.chunk, name=args.name, out=args.out, cache_dir=args.cache_dir, report=args.report,
                   select=select, record=record, progress=not args.no_progress)
    if select:
        from plate_env.build.atlas import select_grid

        select_grid(resolve_grid(job.grid_label()), select)  # an unknown axis or value is refused before any probe
    else:
        resolve_grid(job.grid_label())
    return job


def _sweeps_dir(given: str | None):
    """``--sweeps``, else the user cache directory's ``sweeps/`` (ValueError when the cache is off)."""
    from plate_env.core.cache import cache_dir

    if given is not None:
        return Path(given)
    root = cache_dir()
    if root is None:
        raise ValueError("the cache is off (PLATE_ENV_CACHE_DIR=off): give --sweeps DIR for the simulated sweeps")
    return root / "sweeps"


def run_build(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """Run ``plate-env build``; ``argv`` are the arguments after ``build`` (recorded in the artifact). A file
    written to a shipped file's place gets its manifest entry
    (:func:`plate_env.build.provenance.record_in_manifest`)."""
    from plate_env.build.provenance import build_record, inputs_dir, package_root, record_in_manifest

    record = build_record(argv)
    for name in ("within", "lomo", "faithful"):  # an input not given: the one frozen in plate_env/data/inputs
        if getattr(args, name, "") is None:
            stem = "faithful_forward" if name == "faithful" else f"forward_models_{name}"
            setattr(args, name, inputs_dir() / f"{stem}.json")
    if args.artifact == "suite":
        from plate_env.build.suites import build_suite

        done = build_suite(args.name, args.out, record)
        record_in_manifest(args.out, record)
        print(f"wrote {args.out} (suite {args.name}, sha256 {done['sha256']}) and {args.out}.provenance.json")
        return 0
    if args.artifact == "forward-models":
        from plate_env.build.forward_models import build_forward_models

        reg = build_forward_models(args.within, args.lomo, args.faithful, args.out, record)
        record_in_manifest(args.out, record, {"within": args.within, "lomo": args.lomo, "faithful": args.faithful})
        print(f"wrote {args.out} ({', '.join(reg)}) and {args.out}.provenance.json")
        return 0
    if args.artifact == "calibration" and args.name == "eq10":
        from plate_env.build.eq10 import LAB_AMP_DEG, LAB_SETS, LAB_SIMULATED, RIGID_FAST_CACHE, build_eq10

        lab = args.lab_sweeps if args.lab_sweeps is not None else inputs_dir()
        cals = build_eq10(args.out, record, _sweeps_dir(args.sweeps), lab, args.executor,
                          progress=not args.no_progress)
        record_in_manifest(args.out, record, {**{f: LAB_SETS[f].cache(LAB_AMP_DEG, lab) for f in LAB_SETS
                                                 if f not in LAB_SIMULATED},
                                              "rigid_fast": Path(lab) / RIGID_FAST_CACHE})
        print("\n".join(f"{c.physics}/{c.model}/{c.a_p_deg:g}: p1 = {c.p1_pi:.2f}, q1 = {c.q1_pi:.1f} pi rad/s, "
                        f"R^2 {c.r2:.2f}, {c.n} sweeps" for c in cals))
        print(f"wrote {args.out} and {args.out}.provenance.json")
        return 0
    if args.artifact == "calibration":
        from plate_env.build.calibration import build_calibration

        if args.sweeps is not None or args.lab_sweeps is not None:
            raise ValueError(f"calibration {args.name}: --sweeps and --lab-sweeps are eq10's options")
        body = build_calibration(args.name, args.out, record)
        record_in_manifest(args.out, record)
        print(f"wrote {args.out} (calibration {args.name}, content sha256 {body['content_sha256']}) and "
              f"{args.out}.provenance.json")
        return 0
    if args.artifact == "design-discrepancy":
        from plate_env.build.design_discrepancy import build_design_discrepancy

        content = build_design_discrepancy(args.within, args.out, record)
        record_in_manifest(args.out, record, {"within": args.within})
        print(f"wrote {args.out} ({content['design_discrepancy']}) and {args.out}.provenance.json")
        return 0
    if args.artifact == "pybullet-table":
        from plate_env.build.pybullet_table import build_pybullet_table

        table = build_pybullet_table(args.out, record)
        record_in_manifest(args.out, record)
        print(f"wrote {args.out} ({len(table['k_elastic'])} stiffnesses) and {args.out}.provenance.json")
        return 0
    if args.artifact == "policy":
        raise ValueError("plate-env build policy runs from the command line (plate_env.cli), which may import the "
                         "agents")
    from plate_env.build.atlas import GRIDS, build_atlas

    job = atlas_job(args, record)
    atlas, out, lines = build_atlas(job)
    grid = job.grid_label()
    shipped = package_root("plate_env") / "data" / "grids" / f"{grid}.json"
    grid_file = None if grid in GRIDS else shipped if shipped.is_file() else Path(grid)
    record_in_manifest(out, record, {"grid": grid_file} if grid_file is not None else None)
    print("\n".join(lines))
    print(f"wrote {out} ({atlas.mean.size} nodes)")
    return 0


__all__: Sequence[str] = ("ARTIFACTS", "add_build_parser", "add_policy_parser", "atlas_job", "run_build")
