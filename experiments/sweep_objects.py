"""omega_B(f_p) for the paper's four objects (Fig. 5(b) analogue): table, first-hump peak and plot.

    python experiments/sweep_objects.py [--amp 3] [--model pointmass] [--freqs 10:40:1]

Writes experiments/results/sweep_objects_<physics>_<model>_A<amp>.md and .png.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import plate_env as pe
from plate_env.cli import parse_freqs
from plate_env.identify.fitting import first_hump_mask, fit_results
from plate_env.plotting import new_figure, save_figure


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--amp", type=float, default=3.0, help="A_p, degrees")
    ap.add_argument("--alpha", type=float, default=36.9, help="friction angle, degrees")
    ap.add_argument("--model", default="pointmass")
    ap.add_argument("--freqs", default="10:40:1")
    ap.add_argument("--omegas", default="3.5,10,23,33", help="omega_n values in units of pi rad/s")
    args = ap.parse_args()
    freqs = parse_freqs(args.freqs)
    physics = pe.make_physics("tilelink", model=args.model)
    omegas = [float(w) for w in args.omegas.split(",")]
    stem = f"experiments/results/sweep_objects_tilelink_{args.model}_A{args.amp:g}"
    header = "| f_p [Hz] | " + " | ".join(f"{w:g}pi" for w in omegas) + " |"
    rows: dict[float, list[str]] = {f: [] for f in freqs}
    summary = ["| omega_n [pi rad/s] | first-hump peak f_p [Hz] | peak omega_B [deg/s] | Lorentz f0 [Hz] | b [Hz] "
               "| omega_max [deg/s] | R^2 | probes in window | unstable |", "|---|---|---|---|---|---|---|---|---|"]
    curves = []
    for w in omegas:
        obj = pe.ObjectSpec.from_paper(w, args.alpha)
        res = physics.run([pe.ProbeSpec(obj, pe.PlateMotion.from_paper(f, args.amp)) for f in freqs], progress=True)
        curves.append(res)
        for f, r in zip(freqs, res, strict=True):
            rows[f].append(f"{r.omega_b_deg_s:.0f}" + ("*" if r.unstable else ""))
        om = np.array([r.omega_b_deg_s for r in res])
        usable = np.array([not r.unstable for r in res])
        mask = first_hump_mask(freqs, om, usable)
        k = int(np.argmax(np.where(mask, om, -np.inf)))
        fit = fit_results(res)
        fit_txt = (f"{fit.f0:.2f} ± {fit.f0_stderr:.2f} | {fit.b:.2f} | {fit.omega_max:.0f} | {fit.r2:.3f}"
                   if fit.ok else f"cannot fit: {fit.reason} | | |")
        summary.append(f"| {w:g} | {freqs[k]:g} | {om[k]:.0f} | {fit_txt} | {fit.n_used} | {int((~usable).sum())} |")
    lines = [f"# omega_B(f_p), tilelink {args.model}, A_p = {args.amp:g} deg, B_p = 3 mm, alpha = {args.alpha} deg",
             "", "`*` = unstable probe (value before failure, not used).", "", *summary, "", header,
             "|---" * (len(omegas) + 1) + "|"]
    lines += [f"| {f:g} | " + " | ".join(rows[f]) + " |" for f in freqs]
    with open(stem + ".md", "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines[:len(summary) + 3]))
    fig, ax = new_figure(figsize=(6.5, 4))
    for w, res in zip(omegas, curves, strict=True):
        st = [r for r in res if not r.unstable]
        ax.plot([r.spec.motion.freq_hz for r in st], [r.omega_b_deg_s for r in st], "o-", ms=3,
                label=f"$\\omega_n$ = {w:g}$\\pi$")
    ax.set_xlabel("$f_p$ [Hz]")
    ax.set_ylabel(r"$\omega_B$ [deg/s] (stable probes)")
    ax.set_title(f"tilelink {args.model}, $A_p$ = {args.amp:g}°, $\\alpha$ = {args.alpha}°")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, stem + ".png", dpi=110)
    print(f"wrote {stem}.md/.png ({math.fsum(r.wall_s for c in curves for r in c):.1f} s wall)")


if __name__ == "__main__":
    main()
