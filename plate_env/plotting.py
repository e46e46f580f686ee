"""Plots for sweeps and fits, and the one way the project makes and saves a figure.

matplotlib is imported only when a plot is asked for. Figures are made without pyplot (``matplotlib.figure.Figure``
renders a PNG with the Agg canvas by itself), so the library never chooses a backend for the caller
(``matplotlib.use``) and leaves no figure open in pyplot's global state.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from plate_env.core.probe import ProbeResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from plate_env.bench.report import AgentSummary


def new_figure(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float] | None = None,
               **subplots: Any) -> tuple[Figure, Any]:
    """A figure and its axes, as ``pyplot.subplots(nrows, ncols, figsize=..., **subplots)`` returns them."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **subplots)


def save_figure(fig: Figure, path: str | Path, dpi: int = 100) -> Path:
    """Lay the figure out tightly and write it to ``path`` (format from the suffix) all at once
    (:func:`~plate_env.core.files.write_atomic`); returns the path."""
    from plate_env.core.files import write_atomic

    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi), "plot")
    return Path(path)


def plot_sweep(results: Sequence[ProbeResult], path: str, title: str = "") -> None:
    """omega_B against f_p; stable probes with error bars, unstable ones as crosses at the axis."""
    fig, ax = new_figure(figsize=(6, 4))
    stable = [r for r in results if not r.unstable]
    bad = [r for r in results if r.unstable]
    ax.errorbar([r.spec.motion.freq_hz for r in stable], [r.omega_b_deg_s for r in stable],
                yerr=[r.stderr_deg_s for r in stable], fmt="o-", ms=4, capsize=2, label="stable")
    if bad:
        ax.plot([r.spec.motion.freq_hz for r in bad], [0.0] * len(bad), "x", color="crimson",
                label="unstable (" + ", ".join(sorted({str(r.reason) for r in bad})) + ")")
    ax.set_xlabel("plate frequency $f_p$ [Hz]")
    ax.set_ylabel(r"disc angular velocity $\omega_B$ [deg/s]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path, dpi=110)


def plot_fit(table, est, path: str, fm=None) -> None:
    """Data; per amplitude the fitted curve: the Lorentzian (lorentz) or, for an atlas estimate and its forward model
    ``fm``, the model's mean omega_B at the estimate (:func:`plate_env.identify.inference.predicted_curve`); and the
    omega_n estimate with the posterior (atlas)."""
    import math

    import numpy as np

    fig, (ax, ax2) = new_figure(1, 2, figsize=(10, 4))
    for amp in table.amplitudes():
        sel = np.isclose(table.a_p_deg, amp)
        st = sel & ~table.unstable
        ax.errorbar(table.f_p_hz[st], table.omega_b_deg_s[st], yerr=table.stderr_deg_s[st], fmt="o", ms=4,
                    capsize=2, label=f"A_p = {amp:g} deg")
        if (sel & table.unstable).any():
            ax.plot(table.f_p_hz[sel & table.unstable], np.zeros((sel & table.unstable).sum()), "x", color="crimson")
        fit = est.fits.get(amp)
        if fit is not None and fit.ok:
            ff = np.linspace(table.f_p_hz[sel].min(), table.f_p_hz[sel].max(), 200)
            ax.plot(ff, fit.predict(ff), "-", label=f"Eq. 9: f0 = {fit.f0:.2f} Hz, R^2 = {fit.r2:.3f}")
        if fm is not None:
            from plate_env.identify.inference import predicted_curve

            ff = np.linspace(table.f_p_hz[sel].min(), table.f_p_hz[sel].max(), 200)
            curve = predicted_curve(fm, est, ff, amp)
            if curve is not None:
                ax.plot(ff, curve[0], "-", label=f"{curve[1]} at the estimate, A_p = {amp:g} deg")
    ax.set_xlabel("$f_p$ [Hz]")
    ax.set_ylabel(r"$\omega_B$ [deg/s]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    if est.posterior is not None:
        post = est.posterior
        ax2.plot(post.omega_n / math.pi, post.marginal_omega())
        ax2.set_ylabel("posterior (marginal)")
    if est.ok:
        ax2.axvline(est.omega_n / math.pi, color="k", label=f"estimate {est.omega_n / math.pi:.2f} pi rad/s")
        ax2.axvspan(est.omega_n_ci68[0] / math.pi, est.omega_n_ci68[1] / math.pi, alpha=0.2, label="68 %")
    ax2.set_xlabel(r"$\omega_n$ [$\pi$ rad/s]")
    ax2.grid(alpha=0.3)
    if est.ok:  # nothing labelled to show otherwise
        ax2.legend(fontsize=7)
    save_figure(fig, path, dpi=100)


def plot_curves(summaries: Sequence[AgentSummary], path: str) -> None:
    """A benchmark's curves (:func:`plate_env.bench.summary.board`'s summaries): median (solid) and 90th-percentile
    (dashed) error against the probing budget, one colour per agent."""
    import math

    import numpy as np

    from plate_env.bench.report import rank

    fig, ax = new_figure(figsize=(10.5, 4.8))
    for i, s in enumerate(rank(summaries)):
        colour = f"C{i % 10}"
        x = np.asarray(s.curve_s)
        ax.plot(x, 100 * np.asarray(s.curve_median), "-", color=colour,
                label=f"{s.label} (area {100 * s.area.value:.1f} %)")
        ax.plot(x, 100 * np.asarray(s.curve_p90), "--", color=colour, lw=0.8)
        bx = [b.budget_s for b in s.budgets]
        med = [b.scores.median_error for b in s.budgets]
        ok = [j for j, m in enumerate(med) if math.isfinite(m.value) and math.isfinite(m.hi)]
        ax.errorbar([bx[j] for j in ok], [100 * med[j].value for j in ok],
                    yerr=[[100 * (med[j].value - med[j].lo) for j in ok],
                          [100 * (med[j].hi - med[j].value) for j in ok]],
                    fmt="o", color=colour, ms=4, capsize=3)
    ax.set_yscale("log")
    ax.set_ylim(0.5, 110)
    ax.set_xlabel("probing budget, simulated seconds")
    ax.set_ylabel("relative error of omega_n_hat [%] (capped at 100)")
    ax.set_title(f"{summaries[0].suite}: median (solid, 95 % CI at the budgets) and p90 (dashed)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside: the curves fill the axes
    save_figure(fig, path, dpi=110)
