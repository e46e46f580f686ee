"""Neural posterior estimation with ``sbi`` (issue 13's route comparison), measured against the atlas posterior.

    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 python experiments/npe_sbi.py [--n 20000]

Needs the optional extra (``pip install -e .[sbi]``); plate_env itself never imports sbi.

1. Training data: sweeps of 31 probes (10-40 Hz, 1 Hz, A_p = 3 deg) simulated from the atlas physics
   (``make_physics("atlas")``: omega_B ~ Normal(atlas mean, atlas spread), unstable with the atlas's probability)
   for theta = (log omega_n, alpha deg) drawn from the identification prior (omega_n log-uniform 3.5pi-33pi, alpha
   30-60 deg). The atlas physics answers one probe at a time (~3 ms a probe here, mostly the spline call), so the
   script draws the same distribution vectorised: one ``Atlas.predict`` for all probes, then the physics's own
   draws (stable: mean + spread N(0, 1); unstable with probability p). Placement does not enter the atlas physics'
   distribution (it only seeds its generator), so none is drawn. A check runs a few sweeps through the physics
   itself and asserts it answers from the same atlas. x per frequency: (omega_B / 100 deg/s, 0 if unstable;
   the unstable flag) -> 62 numbers.
2. NPE (sbi NPE_C, MAF density estimator, sbi's default training settings), trained once on the nominal point-mass
   atlas and once on a mixture of the 9 point-mass member atlases (nominal + 8 joint-parameter values; one member
   drawn uniformly per training sweep).
3. Evaluation on the data the atlas method is scored on (experiments/forward_models.py): the within-model test set
   (120 objects, seed 200, live tilelink point mass, 3 deg) against ``identify_atlas`` with the shipped
   ``tilelink/pointmass`` forward model, and the nuisance test set (120 objects, seed 400, each with its own draw of
   the joint/contact values) against the 9-member evidence-pooled family with its measured sigma_eps
   (experiments/results/forward_models_nuisance.json). Per object: 2000 posterior samples, median omega_n and
   equal-tailed 68 %/95 % intervals, scored with ``plate_env.scoring.score`` (95 % bootstrap intervals over
   objects) and paired error differences.

Writes experiments/results/npe_sbi.md and .json and prints the tables.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from common import CACHE

from plate_env.build.forward_models import FAMILIES

RESULTS = Path("experiments/results")
F_HZ = np.arange(10.0, 40.01, 1.0)
A_P_DEG = 3.0
OMEGA_SCALE = 100.0  # deg/s
N_SAMPLES = 2000
#: Raw flow draws per batch and at most per sweep, and the fewest inside the prior that still make an estimate.
BATCH = 2500
MAX_DRAWS = 200_000
MIN_ACCEPTED = 100
#: The results file's hand-written section (kept by a rerun, which rewrites everything above it).
CONCLUSION = "## Conclusion"


# --------------------------------------------------------------------------------------------------- simulation
def prior_bounds() -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of theta = (log omega_n [rad/s], alpha [deg]) under the identification prior."""
    from plate_env.build.eval_sets import PRIOR_ALPHA_DEG, PRIOR_OMEGA_PI

    lo = np.array([math.log(PRIOR_OMEGA_PI[0] * math.pi), PRIOR_ALPHA_DEG[0]])
    hi = np.array([math.log(PRIOR_OMEGA_PI[1] * math.pi), PRIOR_ALPHA_DEG[1]])
    return lo, hi


def draw_theta(n: int, rng: np.random.Generator) -> np.ndarray:
    """theta from the identification prior (prior_objects' draws: log omega_n uniform, then alpha uniform)."""
    lo, hi = prior_bounds()
    return np.stack([rng.uniform(lo[0], hi[0], n), rng.uniform(lo[1], hi[1], n)], axis=1)


def simulate(atlases: list, theta: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Encoded sweeps (n, 62) drawn as ``AtlasPhysics.run`` draws them, one atlas per sweep (uniform over
    ``atlases``), vectorised over all probes."""
    n = len(theta)
    which = rng.integers(0, len(atlases), n)
    omega_b = np.zeros((n, F_HZ.size))
    unstable = np.zeros((n, F_HZ.size), bool)
    for k, atlas in enumerate(atlases):
        idx = np.flatnonzero(which == k)
        if idx.size == 0:
            continue
        w = np.exp(theta[idx, 0])[:, None]
        a = np.radians(theta[idx, 1])[:, None]
        mean, spread, p_un = atlas.predict(F_HZ[None, :], A_P_DEG, w, a)
        un = rng.random(mean.shape) < p_un
        omega_b[idx] = mean + spread * rng.normal(size=mean.shape)
        unstable[idx] = un
    return encode_arrays(omega_b, unstable)


def encode_arrays(omega_b: np.ndarray, unstable: np.ndarray) -> np.ndarray:
    return np.concatenate([np.where(unstable, 0.0, omega_b / OMEGA_SCALE), unstable.astype(float)], axis=-1)


def encode(table) -> np.ndarray:
    """A 10-40 Hz sweep at 3 deg (ProbeTable, probes in frequency order) as the network's 62 numbers."""
    if not (np.allclose(table.f_p_hz, F_HZ) and np.allclose(table.a_p_deg, A_P_DEG)):
        raise ValueError("npe_sbi encodes 10-40 Hz (1 Hz) sweeps at 3 deg only")
    return encode_arrays(np.asarray(table.omega_b_deg_s, float), np.asarray(table.unstable, bool))


def check_physics(atlases: list, names: list[str], rng: np.random.Generator) -> dict:
    """Run a few sweeps through the atlas physics itself: it answers from the same atlas the vectorised draws use
    (so the two give the same distribution); returns its time per probe."""
    from plate_env.build import eval_sets as bm
    from plate_env.physics import make_physics

    out = {}
    for atlas, name in zip(atlases, names, strict=True):
        phys = (make_physics("atlas", source="tilelink", model="pointmass") if name == "atlas_tilelink_pointmass.npz"
                else make_physics("atlas", atlas=atlas))
        specs = bm.placed_sweeps(bm.prior_objects(4, rng), F_HZ, A_P_DEG, rng)
        t0 = time.perf_counter()
        res = phys.run(specs)
        dt = (time.perf_counter() - t0) / len(res)
        for spec in specs:
            got = phys.atlas_for(spec)
            if not all(np.array_equal(getattr(got, k), getattr(atlas, k)) for k in ("mean", "spread", "p_unstable")):
                raise AssertionError(f"atlas physics answers {name} probes from another atlas")
        out[name] = dt
    return out


def emulated_tables(atlases: list, names: list[str], n: int, rng: np.random.Generator) -> tuple[list, list, list]:
    """``n`` prior objects swept (placed) through the atlas physics itself, each from one member drawn uniformly:
    held-out data from the networks' training distribution. Returns truths, tables and members."""
    from plate_env.build import eval_sets as bm
    from plate_env.core.probe_table import ProbeTable
    from plate_env.physics import make_physics

    phys = [make_physics("atlas", source="tilelink", model="pointmass") if name == "atlas_tilelink_pointmass.npz"
            else make_physics("atlas", atlas=atlas) for atlas, name in zip(atlases, names, strict=True)]
    truth, tables, which = [], [], []
    for o in bm.prior_objects(n, rng):
        k = int(rng.integers(0, len(atlases)))
        tables.append(ProbeTable.from_results(phys[k].run(bm.placed_sweeps([o], F_HZ, A_P_DEG, rng))))
        truth.append(o.omega_n)
        which.append(names[k])
    return truth, tables, which


# --------------------------------------------------------------------------------------------------- sbi
def train_npe(x: np.ndarray, theta: np.ndarray, seed: int):
    import torch
    from sbi.inference import NPE
    from sbi.utils import BoxUniform

    torch.manual_seed(seed)
    lo, hi = prior_bounds()
    prior = BoxUniform(torch.tensor(lo, dtype=torch.float32), torch.tensor(hi, dtype=torch.float32))
    from torch.utils.tensorboard import SummaryWriter

    # sbi's training log (tensorboard) in the ignored cache, not ./sbi-logs
    writer = SummaryWriter(log_dir=f"experiments/cache/sbi-logs/npe_seed{seed}_{time.strftime('%Y%m%dT%H%M%S')}")
    inf = NPE(prior=prior, density_estimator="maf", show_progress_bars=False, summary_writer=writer)
    t0 = time.perf_counter()
    est = inf.append_simulations(torch.tensor(theta, dtype=torch.float32), torch.tensor(x, dtype=torch.float32)).train()
    seconds = time.perf_counter() - t0
    summary = inf.summary
    meta = {"train_s": seconds, "epochs": int(summary["epochs_trained"][-1]),
            "best_validation_loss": float(summary["best_validation_loss"][-1])}
    return inf.build_posterior(est), meta


def posterior_samples(posterior, x, rng_seed: int) -> tuple[np.ndarray, float]:
    """Up to N_SAMPLES draws of the NPE posterior inside the prior (sbi's rejection of samples outside the prior's
    support, run here in batches so that a sweep far outside the training distribution, whose flow puts almost
    all its mass outside the prior, cannot stall it: at most MAX_DRAWS raw draws). Returns the accepted samples and
    the accepted share."""
    import torch

    lo, hi = (torch.tensor(b, dtype=torch.float32) for b in prior_bounds())
    kept, drawn, n_kept = [], 0, 0
    while n_kept < N_SAMPLES and drawn < MAX_DRAWS:
        with torch.no_grad():
            s = posterior.sample((BATCH,), x=x, show_progress_bars=False, reject_outside_prior=False)
        drawn += BATCH
        s = s[((s >= lo) & (s <= hi)).all(dim=1)]
        kept.append(s)
        n_kept += len(s)
    s = torch.cat(kept)[:N_SAMPLES].detach().numpy().astype(float)
    return s, n_kept / drawn


def npe_estimates(posterior, tables: list, seed: int) -> tuple[list, float, list[float]]:
    """Per sweep: median omega_n and equal-tailed intervals from N_SAMPLES posterior samples (no estimate when
    fewer than MIN_ACCEPTED of MAX_DRAWS land inside the prior); median seconds; accepted shares."""
    import torch

    from plate_env.identify.estimate import Estimate

    torch.manual_seed(seed)
    out, secs, shares = [], [], []
    for t in tables:
        t0 = time.perf_counter()
        x = torch.tensor(encode(t), dtype=torch.float32)
        s, share = posterior_samples(posterior, x, seed)
        shares.append(share)
        base = {"method": "npe", "n_probes": len(t), "n_unstable": int(t.unstable.sum()), "forward": "npe"}
        if len(s) < MIN_ACCEPTED:
            out.append(Estimate(ok=False, reason=f"NPE posterior outside the prior ({share:.2%} of draws inside): the "
                                "sweep lies outside the network's training distribution", **base))
        else:
            w = np.exp(s[:, 0])
            q = np.quantile(w, [0.025, 0.16, 0.5, 0.84, 0.975])
            a = np.radians(s[:, 1])
            out.append(Estimate(ok=True, omega_n=float(q[2]), omega_n_stderr=float((q[3] - q[1]) / 2),
                                omega_n_ci68=(float(q[1]), float(q[3])), omega_n_ci95=(float(q[0]), float(q[4])),
                                alpha=float(np.median(a)), alpha_stderr=float(np.std(a)), **base))
        secs.append(time.perf_counter() - t0)
    return out, float(np.median(secs)), shares


def atlas_estimates(fm, tables: list) -> tuple[list, float, None]:
    from plate_env.identify.inference import identify_atlas

    out, secs = [], []
    for t in tables:
        t0 = time.perf_counter()
        out.append(identify_atlas(t, fm))
        secs.append(time.perf_counter() - t0)
    return out, float(np.median(secs)), None


# --------------------------------------------------------------------------------------------------- report
HEAD = ["| data, method | objects | median error | p90 error | 68 % coverage | 95 % coverage | "
        "median 95 % width / omega_n | no estimate | wall s / object (median) |", "|---|" + "---|" * 8]


def row(label: str, s, secs: float) -> str:
    return (f"| {label} | {s.n} | {s.median_error.fmt(100, 1, ' %')} | {s.p90_error.fmt(100, 1, ' %')} | "
            f"{s.coverage68.fmt(1, 2)} | {s.coverage95.fmt(1, 2)} | {s.width95.fmt(100, 0, ' %')} | "
            f"{s.no_estimate.fmt(1, 2)} | {secs:.3g} |")


def scored(ests: dict, labels: dict, truth: list, rng) -> tuple[list[str], dict, list[str]]:
    """Table rows, numbers and notes (NPE draws inside the prior) for one data set's methods."""
    from plate_env.bench.scoring import score

    rows, numbers, notes = [], {}, []
    for k, (e, secs, shares) in ests.items():
        s = score(truth, e, rng)
        rows.append(row(labels[k], s, secs))
        numbers[k] = {**s.to_dict(), "wall_s_per_object": secs}
        if shares is not None:
            sh = np.array(shares)
            numbers[k]["inside_prior_share"] = sh.tolist()
            notes.append(f"{labels[k]}: share of raw flow draws inside the prior, median {np.median(sh):.2f}; "
                         f"below 0.5 on {int(np.sum(sh < 0.5))} of {sh.size} objects; no estimate (fewer than "
                         f"{MIN_ACCEPTED} of {MAX_DRAWS} inside) on {int(sum(not x.ok for x in e))}.")
    return rows, numbers, notes


def paired(label_a: str, a: list, label_b: str, b: list, truth: list, rng) -> tuple[str, dict]:
    from plate_env.bench.scoring import paired_difference

    ea = [e.relative_error(w) for e, w in zip(a, truth, strict=True)]
    eb = [e.relative_error(w) for e, w in zip(b, truth, strict=True)]
    d = paired_difference(ea, eb, rng)
    text = (f"Paired per-object error difference, {label_a} minus {label_b} (median, 95 % bootstrap): "
            f"{d.fmt(100, 1, ' points')}.")
    return text, d.to_dict()


def train_networks(args, atlases: list, rng: np.random.Generator, numbers: dict) -> dict:
    """The two networks (nominal atlas, 9-member mixture), trained or loaded from experiments/cache; their training
    numbers go into ``numbers``."""
    import torch

    nets = {}
    for key, members in (("nominal", atlases[:1]), ("family", atlases)):
        t0 = time.perf_counter()
        theta = draw_theta(args.n, rng)
        x = simulate(members, theta, rng)
        sim_s = time.perf_counter() - t0
        cache = Path(f"experiments/cache/npe_sbi_{key}_n{args.n}_s{args.seed}.pt")
        if cache.exists() and not args.retrain:
            post, meta = torch.load(cache, weights_only=False)
        else:
            post, meta = train_npe(x, theta, args.seed)
            cache.parent.mkdir(parents=True, exist_ok=True)
            torch.save((post, meta), cache)
        nets[key] = post
        numbers[f"npe_{key}"] = {"members": len(members), "simulate_s": sim_s, **meta,
                                 "unstable_share": float(x[:, F_HZ.size:].mean())}
        print(f"NPE {key}: {args.n} sweeps simulated in {sim_s:.1f} s, trained in {meta['train_s']:.0f} s "
              f"({meta['epochs']} epochs)", file=sys.stderr, flush=True)
    return nets


def emulated_section(args, atlases: list, names: list[str], nets: dict, fm, bma, numbers: dict,
                     srng: np.random.Generator) -> list[str]:
    """Held-out sweeps of the atlas physics itself (the training distribution): the report's lines, numbers into
    ``numbers``."""
    emu_lines: list[str] = []
    if args.emulated:
        erng = np.random.default_rng(args.seed + 1000)
        n_emu = args.limit or args.emulated
        emu_rows, numbers["emulated"] = [], {}
        for key, members, mnames, fm_e, label in (
                ("nominal", atlases[:1], names[:1], fm, f"atlas posterior (tilelink/pointmass, sigma_eps "
                                                        f"{fm.sigma_eps:.3f})"),
                ("family", atlases, names, dataclasses.replace(bma, sigma_eps=0.0),
                 "atlas family, evidence-pooled (BMA), sigma_eps 0")):
            truth_e, tables_e, _ = emulated_tables(members, mnames, n_emu, erng)
            ests_e = {"atlas": atlas_estimates(fm_e, tables_e), "npe": npe_estimates(nets[key], tables_e, 5)}
            rows_e, numbers["emulated"][key], notes_e = scored(
                ests_e, {"atlas": f"{key} atlas physics data, {label}",
                         "npe": f"{key} atlas physics data, sbi NPE trained on the {key} atlas"
                                f"{' mixture' if key == 'family' else ''}"}, truth_e, srng)
            emu_rows += rows_e
        emu_lines = ["## In the training distribution: held-out sweeps of the atlas physics itself", "",
                     f"{n_emu} prior objects per row pair (seed {args.seed + 1000}), each swept through "
                     "`make_physics(\"atlas\")` (family: a member drawn uniformly per object); both methods see the "
                     "same tables. This separates the network's own amortisation error from the gap between the "
                     "atlas emulator and live physics.", "", *HEAD, *emu_rows, ""]
    return emu_lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=20000, help="training sweeps per NPE")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--emulated", type=int, default=120, help="held-out atlas-physics objects per network (0: none)")
    ap.add_argument("--out", default="npe_sbi", help="results file stem in experiments/results")
    ap.add_argument("--retrain", action="store_true", help="train even if experiments/cache holds the networks")
    ap.add_argument("--limit", type=int, default=0, help="smoke test: score only the first LIMIT objects (no files)")
    args = ap.parse_args()
    for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(k, "1")
    import torch

    torch.set_num_threads(1)
    import common

    from plate_env.build.eval_sets import run_eval_set
    from plate_env.identify.forward import ForwardModel, load_forward_model
    from plate_env.surrogate.atlas import load_atlas_file
    rng = np.random.default_rng(args.seed)
    names = FAMILIES["pointmass"]
    atlases = [load_atlas_file(n) for n in names]
    physics_s = check_physics(atlases, names, rng)
    numbers: dict = {"n_train": args.n, "n_samples": N_SAMPLES, "atlas_physics_s_per_probe": physics_s}

    nets = train_networks(args, atlases, rng, numbers)

    # ---- within model: the forward_models TEST set at 3 deg
    srng = np.random.default_rng(0)
    test = run_eval_set(common.TEST, lambda _: common.POINTMASS, cache_dir=CACHE)[A_P_DEG]
    truth = [o.omega_n for o in common.TEST.objects()]
    if args.limit:
        test, truth = test[:args.limit], truth[:args.limit]
    fm = load_forward_model("tilelink/pointmass")
    ests = {"atlas": atlas_estimates(fm, test), "npe_nominal": npe_estimates(nets["nominal"], test, 1),
            "npe_family": npe_estimates(nets["family"], test, 2)}
    labels = {"atlas": f"atlas posterior (identify_atlas, tilelink/pointmass, sigma_eps {fm.sigma_eps:.3f})",
              "npe_nominal": "sbi NPE trained on the nominal atlas",
              "npe_family": "sbi NPE trained on the 9-member atlas mixture"}
    within_rows, numbers["within"], notes_w = scored(ests, labels, truth, srng)
    txt_w, numbers["within"]["paired_npe_nominal_minus_atlas"] = paired(
        "NPE (nominal)", ests["npe_nominal"][0], "atlas", ests["atlas"][0], truth, srng)

    # ---- nuisances integrated out: the forward_models nuisance test set
    nu = json.loads((RESULTS / "forward_models_nuisance.json").read_text())
    bma_key = next(k for k in nu if k.startswith("nuisance family"))
    sigma_bma = float(nu[bma_key]["sigma_eps"])
    truth_n, test_n = common.data_of("pointmass", None)
    if args.limit:
        test_n, truth_n = test_n[:args.limit], truth_n[:args.limit]
    bma = ForwardModel(bma_key, tuple(common.member(f) for f in names), sigma_eps=sigma_bma,
                       eps_nu=float(nu[bma_key].get("eps_nu", math.inf)))
    ests_n = {"bma": atlas_estimates(bma, test_n), "npe_family": npe_estimates(nets["family"], test_n, 3),
              "npe_nominal": npe_estimates(nets["nominal"], test_n, 4)}
    labels_n = {"bma": f"atlas family, evidence-pooled (BMA), 9 members, sigma_eps {sigma_bma:.3f}",
                "npe_family": "sbi NPE trained on the 9-member atlas mixture",
                "npe_nominal": "sbi NPE trained on the nominal atlas only"}
    nuis_rows, numbers["nuisance"], notes_n = scored(ests_n, labels_n, truth_n, srng)
    txt_n, numbers["nuisance"]["paired_npe_family_minus_bma"] = paired(
        "NPE (mixture)", ests_n["npe_family"][0], "BMA", ests_n["bma"][0], truth_n, srng)
    numbers["nuisance"]["bma_shipped_result"] = nu[bma_key]

    emu_lines = emulated_section(args, atlases, names, nets, fm, bma, numbers, srng)

    nn, nf = numbers["npe_nominal"], numbers["npe_family"]
    lines = [
        "# Neural posterior estimation (sbi) against the atlas posterior (issue 13)", "",
        f"Command: `OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 python experiments/npe_sbi.py --n {args.n}"
        f"{'' if args.seed == 0 else f' --seed {args.seed}'}{'' if args.out == 'npe_sbi' else f' --out {args.out}'}` "
        f"(sbi 0.27.0, torch CPU, 1 thread, a shared 2-core machine).", "",
        f"Training: {args.n} sweeps per network (10-40 Hz, 1 Hz, A_p = 3 deg), theta = (log omega_n, alpha) from the "
        "identification prior, simulated from the atlas physics' distribution (vectorised; the physics itself takes "
        f"{1e3 * np.median(list(physics_s.values())):.1f} ms a probe here, median over the atlases; checked to "
        "answer from the same atlases). "
        "x: omega_B / 100 deg/s (0 if unstable) and the unstable flag per frequency (62 numbers). sbi NPE_C with a "
        "MAF (5 transforms, 50 hidden), default training (batch 200, lr 5e-4, 10 % validation, stop after 20 "
        "epochs without improvement).", "",
        f"- nominal atlas: simulated in {nn['simulate_s']:.1f} s, trained in {nn['train_s']:.0f} s "
        f"({nn['epochs']} epochs)",
        f"- 9-member mixture: simulated in {nf['simulate_s']:.1f} s, trained in {nf['train_s']:.0f} s "
        f"({nf['epochs']} epochs)", "",
        f"Per object: {N_SAMPLES} posterior samples, median omega_n, equal-tailed 68 %/95 % intervals. Scores: "
        "plate_env.bench.scoring.score, 95 % bootstrap intervals over objects in brackets. Wall time per object: the "
        "median over objects (atlas: identify_atlas; NPE: encoding + sampling; training not included).", "",
        f"## Within the model: live tilelink point mass, test set of experiments/forward_models.py ({common.TEST.n} "
        f"objects, seed {common.TEST.seed}, 3 deg sweeps)", "", *HEAD, *within_rows, "", txt_w, "",
        *[f"- {t}" for t in notes_w], "",
        f"## Unknown joint/contact values: nuisance test set ({common.DATA['pointmass'].n} objects, seed "
        f"{common.DATA['pointmass'].seed}, each with its own draw)", "", *HEAD, *nuis_rows, "", txt_n, "",
        *[f"- {t}" for t in notes_n], "", *emu_lines,
        f"(The BMA row is recomputed here with the shipped sigma_eps; experiments/results/forward_models_nuisance.md "
        f"reports median {100 * nu[bma_key]['median_error']['value']:.1f} %, p90 "
        f"{100 * nu[bma_key]['p90_error']['value']:.1f} %, cov68 {nu[bma_key]['coverage68']['value']:.2f}, cov95 "
        f"{nu[bma_key]['coverage95']['value']:.2f}, width {100 * nu[bma_key]['width95']['value']:.0f} %.)", "",
    ]
    print("\n".join(lines))
    if args.limit:
        return
    RESULTS.mkdir(parents=True, exist_ok=True)
    md = RESULTS / f"{args.out}.md"
    # the hand-written conclusion (its own section, read from the tables) is kept: a rerun must re-read it
    old = md.read_text() if md.exists() else ""
    tail = old[old.index(CONCLUSION):] if CONCLUSION in old else ""
    md.write_text("\n".join(lines) + "\n" + tail)
    (RESULTS / f"{args.out}.json").write_text(json.dumps(numbers, indent=1) + "\n")


if __name__ == "__main__":
    main()
