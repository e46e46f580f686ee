"""Score atlas identification on the PyBullet backend with held-out objects.

    python experiments/evaluate_pybullet.py [--sigma-model 15]

Held-out objects (plate_env.benchmarks.PYBULLET_HELD_OUT_OBJECTS: no omega_n or alpha value on the pybullet atlas
grid) are swept over the atlas's frequencies (10-26 Hz, 2 Hz) at A_p = 3 deg, B_p = 3 mm, with the atlas's probe
windows (read from its provenance), centred placement (as the atlas grid was run), one
process. Each sweep is identified with ``identify(..., method="atlas", physics="pybullet", model=...)``: median and
90th-percentile relative error of omega_n_hat, 1-sigma coverage, alpha error. Also scores the atlas itself on
these probes (prediction error at held-out (omega_n, alpha)). Resumable cache:
experiments/cache/heldout_pybullet_<model>.jsonl. Writes experiments/results/identification_pybullet_<model>.md.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import plate_env as pe
from plate_env.bench.reporting import median_p90
from plate_env.build import eval_sets as bm
from plate_env.core.probe_table import ProbeTable
from plate_env.identify import identify
from plate_env.identify.forward import ForwardModel, Member
from plate_env.run.executor import BackendSpec, add_executor_argument
from plate_env.run.sweeps import run_cached
from plate_env.surrogate.atlas import Atlas, load_atlas

#: The pybullet atlas's model error scored by default, deg/s (the grid's own leave-one-omega_n-out scale, below).
SIGMA_MODEL = 15.0


def loo_error(atlas: Atlas) -> np.ndarray:
    """Leave-one-omega_n-out error of the atlas on its own grid (signed, deg/s, stable grid points only).

    Each interior omega_n column is dropped, the rest re-interpolated and predicted at the dropped column: a
    grid-only (no held-out data) estimate of the interpolation error, pessimistic (the spacing doubles)."""
    errs = []
    for k in range(1, len(atlas.omega_n) - 1):
        keep = [i for i in range(len(atlas.omega_n)) if i != k]
        sub = Atlas(physics=atlas.physics, model=atlas.model, f_hz=atlas.f_hz, a_p_deg=atlas.a_p_deg,
                    omega_n=atlas.omega_n[keep], alpha=atlas.alpha, mean=atlas.mean[:, :, keep],
                    spread=atlas.spread[:, :, keep], p_unstable=atlas.p_unstable[:, :, keep],
                    n_repeats=atlas.n_repeats)
        for i_f, i_a, i_al in np.ndindex(len(atlas.f_hz), len(atlas.a_p_deg), len(atlas.alpha)):
            if atlas.p_unstable[i_f, i_a, k, i_al] > 0.5:
                continue
            mu, _, _ = sub.predict(atlas.f_hz[i_f], atlas.a_p_deg[i_a], atlas.omega_n[k], atlas.alpha[i_al])
            errs.append(float(atlas.mean[i_f, i_a, k, i_al] - mu))
    return np.array(errs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sigma-model", type=float, nargs="*", default=[SIGMA_MODEL],
                    help="atlas model error(s), deg/s, to score (the first is the headline)")
    add_executor_argument(ap)
    args = ap.parse_args()
    backend = BackendSpec.of("pybullet", n_workers=1)
    physics = backend.build()  # its settings for the report; the probes run on the executor
    model = getattr(physics, "model", "pybullet")
    atlas = load_atlas("pybullet", model)
    prov = atlas.provenance
    settle, measure = float(prov["settle_s"]), float(prov["measure_s"])
    f = [float(x) for x in atlas.f_hz]
    amp = float(atlas.a_p_deg[0])
    objs = [pe.ObjectSpec.from_paper(w, a) for w, a in bm.PYBULLET_HELD_OUT_OBJECTS]
    specs = [s for o in objs for s in bm.sweep_specs(o, f, amp, settle_s=settle, measure_s=measure)]
    res = run_cached(backend, specs, f"experiments/cache/heldout_pybullet_{model}.jsonl", chunk=len(f),
                     executor=args.executor,
                     desc="held-out sweeps")
    physics.close()
    n = len(f)
    tables = [ProbeTable.from_results(res[i * n:(i + 1) * n]) for i in range(len(objs))]
    wall = sum(r.wall_s for r in res)
    # the atlas against these live probes
    errs, zs, pus, uns = [], [], [], []
    for r in res:
        mu, s, p = atlas.predict(r.spec.motion.freq_hz, amp, r.spec.obj.omega_n, r.spec.obj.alpha)
        pus.append(float(p))
        uns.append(float(r.unstable))
        if not r.unstable:
            errs.append(abs(r.omega_b_deg_s - float(mu)))
            zs.append((r.omega_b_deg_s - float(mu)) / max(float(s), 1e-9))
    errs_a = np.array(errs)
    brier = float(np.mean((np.array(pus) - np.array(uns)) ** 2))
    atlas_med, atlas_p90 = median_p90(errs_a)
    lines = ["# Identification on held-out objects: pybullet / " + model, "",
             f"{len(objs)} held-out objects (omega_n pi, alpha deg): {bm.PYBULLET_HELD_OUT_OBJECTS}, none on the "
             f"atlas grid (omega_n {list(prov['omega_n_pi'])} pi, alpha {list(prov['alpha_deg'])} deg). Sweeps "
             f"{f[0]:g}-{f[-1]:g} Hz step {f[1] - f[0]:g} Hz at A_p = {amp:g} deg, B_p = 3 mm, 0.2 s ramp + "
             f"{settle:g} s settle + {measure:g} s measure (the atlas's windows), centred placement, sequences of "
             f"{physics.sequence_len} probes per scene (as in the atlas build). {len(res)} probes, "
             f"{wall / 60:.1f} min of probe wall time. Regenerate: `python experiments/evaluate_pybullet.py`.", "",
             "## The atlas against these live probes (held-out omega_n and alpha, on-grid f_p)", "",
             "| probes | stable | median abs error [deg/s] | 90th pct [deg/s] | median abs z | "
             "instability Brier (0.25 = coin) | observed unstable share |", "|---|---|---|---|---|---|---|",
             f"| {len(res)} | {len(errs)} | {atlas_med:.1f} | {atlas_p90:.1f} | "
             f"{np.median(np.abs(zs)):.2f} | {brier:.3f} | {np.mean(uns):.2f} |", ""]
    loo = np.abs(loo_error(atlas))
    loo_med, loo_p90 = median_p90(loo)
    lines += [f"Leave-one-omega_n-out on the grid itself ({len(loo)} stable points): median abs error "
              f"{loo_med:.1f} deg/s, 90th pct {loo_p90:.0f} deg/s, robust scale 1.4826 x "
              f"median {1.4826 * loo_med:.1f} deg/s: the default sigma_model ({SIGMA_MODEL:g} deg/s) matches "
              "it, so it is kept as the headline (chosen from the grid, not from the held-out results); the "
              "heavy tail is left to the Student-t likelihood. The between-placement spread folded into the atlas "
              f"(provenance: {atlas.provenance.get('spread_floor', {}).get('abs_deg_s', float('nan')):.1f} deg/s, "
              f"{100 * atlas.provenance.get('spread_floor', {}).get('rel', float('nan')):.1f} %) is far smaller.", ""]
    summary = ["## Identification (atlas posterior)", "",
               "| sigma_model [deg/s] | median rel. error | 90th pct | 1-sigma coverage | 2-sigma (95 % CI) coverage | "
               "failed | alpha median abs error [deg] |", "|---|---|---|---|---|---|---|"]
    per_obj = {}
    for sm in args.sigma_model:
        fm = ForwardModel(f"pybullet/{model} (sigma_model {sm:g})", (Member(atlas, sm),))
        ests = [identify(t, method="atlas", forward=fm) for t in tables]
        ok = [(o, e) for o, e in zip(objs, ests, strict=True) if e.ok]
        rel = np.array([e.relative_error(o.omega_n) for o, e in ok])
        cov1 = np.mean([abs(e.omega_n - o.omega_n) <= e.omega_n_stderr for o, e in ok])
        cov2 = np.mean([e.omega_n_ci95[0] <= o.omega_n <= e.omega_n_ci95[1] for o, e in ok])
        aerr = np.median([abs(math.degrees(e.alpha - o.alpha)) for o, e in ok])
        rel_med, rel_p90 = median_p90(rel)
        summary.append(f"| {sm:g} | {100 * rel_med:.1f} % | {100 * rel_p90:.1f} % | "
                       f"{100 * cov1:.0f} % | {100 * cov2:.0f} % | {len(objs) - len(ok)}/{len(objs)} | {aerr:.1f} |")
        per_obj[sm] = ests
    sm0 = args.sigma_model[0]
    detail = ["", f"Per object (sigma_model = {sm0:g} deg/s):", "",
              "| omega_n [pi] | alpha [deg] | omega_n_hat [pi] | 1-sigma [pi] | rel. error | alpha_hat [deg] | "
              "unstable probes | sweep (deg/s, u = unstable) |", "|---|---|---|---|---|---|---|---|"]
    for o, e, t in zip(objs, per_obj[sm0], tables, strict=True):
        sweep = " ".join(f"{y:.0f}" + ("u" if u else "") for y, u in zip(t.omega_b_deg_s, t.unstable, strict=True))
        detail.append(f"| {o.omega_n / math.pi:.1f} | {math.degrees(o.alpha):.0f} | {e.omega_n / math.pi:.2f} | "
                      f"{e.omega_n_stderr / math.pi:.2f} | {100 * e.relative_error(o.omega_n):.1f} % | "
                      f"{math.degrees(e.alpha):.1f} | {e.n_unstable}/{e.n_probes} | {sweep} |")
    lines += summary + detail
    lines += ["", "What limits it: the PyBullet response carries omega_n information only on its rising edge "
              "(~16-22 Hz at 3 deg), where it is steep, non-monotone between neighbouring omega_n grid columns and "
              "often cut by slip/fold (stable/unstable flips from probe to probe); below 16 Hz the curves of all "
              "omega_n coincide (they carry alpha). With one repeat per grid point the atlas mean is one noisy run "
              "and p_unstable is 0 or 1; the 7-point omega_n axis is coarse for such a jumpy surface (the "
              "leave-one-out tail). Seven held-out objects make the median and the 90th percentile coarse (the "
              "median is the 4th object)."]
    path = f"experiments/results/identification_pybullet_{model}.md"
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
