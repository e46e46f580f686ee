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


#: The look every command's plot shares: legend font size, grid, dots per inch of the PNG.
LEGEND_FONTSIZE = 7
GRID_ALPHA = 0.3
DPI = 100
#: A posterior panel's x axis is logarithmic when its window spans more than this factor (hi / lo).
LOG_AXIS_RATIO = 4.0
#: The model predicts an unstable probe where its p_unstable is at least this.
UNSTABLE_P = 0.5
UNSTABLE_COLOUR = "crimson"


def _finish(fig: Figure, path: str | Path | None, dpi: int | None) -> Figure:
    """Save ``fig`` to ``path`` at ``dpi`` (None: :data:`DPI`, read now) and return it; ``path`` None: not
    written, for a caller that only inspects the figure."""
    if path is not None:
        save_figure(fig, path, dpi=DPI if dpi is None else dpi)
    return fig


def _amp_label(amp: float) -> str:
    return f"A_p = {amp:g} deg"


def draw_probes(ax, table, *, guide: bool = False, reasons: Sequence[str] = ()) -> dict[float, str]:
    """The probes of ``table`` (a :class:`~plate_env.core.probe_table.ProbeTable`) on ``ax``: per amplitude one
    colour, stable probes as points with their standard errors, unstable ones as crosses at omega_B = 0 (they have
    no steady omega_B). ``guide``: a thin line joins neighbouring stable probes, broken at every unstable one (a
    sweep's eye guide; it claims nothing between probes across an instability). ``reasons``: why probes were
    unstable, named in the legend. Returns the colour of each amplitude (``table.amplitudes()``)."""
    import numpy as np

    colours = {}
    for k, amp in enumerate(table.amplitudes()):
        colour = colours[amp] = f"C{k % 10}"
        sel = np.isclose(table.a_p_deg, amp, atol=1e-6)
        order = np.argsort(table.f_p_hz[sel], kind="stable")
        f, y = table.f_p_hz[sel][order], table.omega_b_deg_s[sel][order]
        e, bad = table.stderr_deg_s[sel][order], table.unstable[sel][order]
        if (~bad).any():
            ax.errorbar(f[~bad], y[~bad], yerr=e[~bad], fmt="o", ms=4, capsize=2, color=colour,
                        label=f"{_amp_label(amp)}: stable probes")
            if guide:
                ax.plot(f, np.where(bad, np.nan, y), "-", lw=1.0, color=colour, alpha=0.6)
        if bad.any():
            why = f" ({', '.join(sorted(set(reasons)))})" if reasons else ""
            ax.plot(f[bad], np.zeros(bad.sum()), "x", ms=7, mew=1.5, color=colour if len(table.amplitudes()) > 1
                    else UNSTABLE_COLOUR, label=f"{_amp_label(amp)}: unstable probes{why}, drawn at 0")
    ax.set_xlabel("plate frequency $f_p$ [Hz]")
    ax.set_ylabel(r"disc angular velocity $\omega_B$ [deg/s]")
    ax.grid(alpha=GRID_ALPHA)
    return colours


def _curve_grid(table, n: int = 400):
    """The frequencies a model curve is drawn at: the probed range (every amplitude's), 1 Hz either side of a
    single probed frequency."""
    import numpy as np

    lo, hi = float(table.f_p_hz.min()), float(table.f_p_hz.max())
    if hi - lo < 1e-9:
        lo, hi = lo - 1.0, hi + 1.0
    return np.linspace(lo, hi, n)


def draw_model(ax, table, est, fm, colours: dict[float, str]) -> None:
    """Per amplitude, the curve the estimate says the data follow, in the amplitude's colour: the Lorentzian
    (lorentz; over its stable probes' range) or the forward model's mean omega_B at the estimate (atlas;
    :func:`plate_env.identify.inference.predicted_curve`) over the whole probed range, drawn only where the model
    predicts stable probes; where it predicts instability (p_unstable >= :data:`UNSTABLE_P`) a translucent band
    lies at omega_B = 0, where an unstable probe is drawn."""
    import numpy as np

    for amp, colour in colours.items():
        sel = np.isclose(table.a_p_deg, amp, atol=1e-6)
        fit = est.fits.get(amp)
        st = sel & ~table.unstable
        if fit is not None and fit.ok and st.sum() > 1:
            ff = np.linspace(table.f_p_hz[st].min(), table.f_p_hz[st].max(), 200)
            ax.plot(ff, fit.predict(ff), "-", color=colour,
                    label=f"{_amp_label(amp)}: Eq. 9 fit, f0 = {fit.f0:.2f} Hz, R^2 = {fit.r2:.3f}")
        if fm is None:
            continue
        from plate_env.identify.inference import predicted_curve

        curve = predicted_curve(fm, est, _curve_grid(table), amp)
        if curve is None:
            continue
        stable = curve.predicts_stable(UNSTABLE_P)
        if stable.any():
            ax.plot(curve.f_hz, np.where(stable, curve.mean, np.nan), "-", color=colour,
                    label=f"{_amp_label(amp)}: {curve.label} at the estimate")
        unstable = curve.inside & ~stable
        if unstable.any():
            ax.plot(curve.f_hz, np.where(unstable, 0.0, np.nan), "-", lw=7, alpha=0.25, color=colour,
                    solid_capstyle="butt",
                    label=f"{_amp_label(amp)}: model predicts unstable probes (p >= {UNSTABLE_P:g})")


def posterior_window(est, omega_n_true: float | None = None) -> tuple[float, float, bool]:
    """``(lo, hi, log)``: the omega_n range (rad/s) a posterior panel shows and whether its axis is logarithmic. An
    estimate: its 95 % interval (and the truth, when known), padded by 15 % of its width on either side (in log
    omega_n when the window spans more than :data:`LOG_AXIS_RATIO`; linear from 0 when it reaches 0). A bound: from a
    third of it to the grid's top ("above") or from the grid's bottom to three times it ("below"; without a grid a
    decade beyond it). Otherwise the whole posterior grid, or a factor 3 either side of the truth, or 1-1000 rad/s."""
    import math

    post = est.posterior
    grid = (float(post.omega_n[0]), float(post.omega_n[-1])) if post is not None else None
    if est.ok:
        lo, hi = est.omega_n_ci95
    elif est.bound is not None:
        side, x = est.bound
        lo, hi = (x / 3, grid[1] if grid else 10 * x) if side == "above" else (grid[0] if grid else x / 10, 3 * x)
    elif grid is not None:
        lo, hi = grid
    elif omega_n_true is not None:
        lo, hi = omega_n_true / 3, omega_n_true * 3
    else:
        lo, hi = 1.0, 1000.0
    if omega_n_true is not None:
        lo, hi = min(lo, omega_n_true), max(hi, omega_n_true)
    if lo <= 0.0:  # an interval reaching zero (the Lorentz method's, say) has no log scale: linear from 0
        hi = max(hi, 1e-9)
        return 0.0, 1.15 * hi, False
    hi = max(hi, lo * (1 + 1e-6))
    log = hi / lo > LOG_AXIS_RATIO
    if log:
        pad = 0.15 * math.log(hi / lo)
        return lo * math.exp(-pad), hi * math.exp(pad), True
    pad = 0.15 * (hi - lo)
    return max(lo - pad, 0.0), hi + pad, False


def draw_posterior(ax, est, omega_n_true: float | None = None) -> None:
    """omega_n on ``ax`` in pi rad/s, on the window of :func:`posterior_window`: the posterior density per unit
    ln omega_n (the grid is log-spaced), the estimate (solid line), its 68 % and 95 % intervals (bands), a bound
    (dotted) and the true omega_n when known (dashed). The title states the estimate and its 68 % interval or why
    there is none."""
    import math

    import numpy as np
    from matplotlib.ticker import FuncFormatter

    lo, hi, log = posterior_window(est, omega_n_true)
    post = est.posterior
    if post is not None:
        w = np.asarray(post.omega_n, float)
        dens = post.marginal_omega() / np.gradient(np.log(w)) if w.size > 1 else post.marginal_omega()
        ax.plot(w / math.pi, dens, "-", color="C0", label="posterior density per unit ln omega_n")
        inside = (w >= lo) & (w <= hi)
        top = float(dens[inside].max()) if inside.any() else float(dens.max())
        ax.set_ylim(0.0, 1.1 * top if top > 0 else 1.0)
        ax.set_ylabel(r"posterior density per unit ln $\omega_n$")
    else:
        ax.set_yticks([])
    if est.ok:
        ax.axvspan(est.omega_n_ci95[0] / math.pi, est.omega_n_ci95[1] / math.pi, color="C0", alpha=0.12,
                   label=f"95 %: {est.omega_n_ci95[0] / math.pi:.3g}-{est.omega_n_ci95[1] / math.pi:.3g} pi")
        ax.axvspan(est.omega_n_ci68[0] / math.pi, est.omega_n_ci68[1] / math.pi, color="C0", alpha=0.3,
                   label=f"68 %: {est.omega_n_ci68[0] / math.pi:.3g}-{est.omega_n_ci68[1] / math.pi:.3g} pi")
        ax.axvline(est.omega_n / math.pi, color="k", lw=1.5, label=f"estimate {est.omega_n / math.pi:.4g} pi")
        ax.set_title(f"omega_n_hat = {est.omega_n / math.pi:.4g} pi rad/s, 68 % "
                     f"{est.omega_n_ci68[0] / math.pi:.3g}-{est.omega_n_ci68[1] / math.pi:.3g} pi", fontsize=9)
    elif est.bound is not None:
        side, x = est.bound
        ax.axvline(x / math.pi, color="k", ls=":", lw=1.5,
                   label=f"bound: omega_n {'>' if side == 'above' else '<'} {x / math.pi:.3g} pi (95 %)")
        ax.set_title(f"no estimate, a bound: omega_n {'>' if side == 'above' else '<'} {x / math.pi:.3g} pi rad/s",
                     fontsize=9)
    else:
        reason = str(est.reason or "")
        ax.set_title("no estimate" + (f": {reason[:60]}..." if len(reason) > 60 else f": {reason}" if reason else ""),
                     fontsize=9)
    if omega_n_true is not None:
        ax.axvline(omega_n_true / math.pi, color=UNSTABLE_COLOUR, ls="--", lw=1.5,
                   label=f"true omega_n = {omega_n_true / math.pi:.4g} pi")
    if log:
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.set_xlim(lo / math.pi, hi / math.pi)
    ax.set_xlabel(r"$\omega_n$ [$\pi$ rad/s]" + (" (log axis)" if log else ""))
    ax.grid(alpha=GRID_ALPHA, which="both" if log else "major")


#: The order of a data panel's legend entries within one amplitude, by how the text after ``A_p = X deg: ``
#: begins (a model curve, named by its model, comes between the probes and the predicted instability).
_ENTRY_ORDER = ("stable probes", "unstable probes", "", "model predicts")


def _entry_key(label: str) -> tuple[float, int]:
    """Legend order: by amplitude (labels ``A_p = X deg: ...``), then :data:`_ENTRY_ORDER`; others last."""
    if not label.startswith("A_p = ") or ": " not in label:
        return float("inf"), 0
    head, rest = label.split(": ", 1)
    rank = next((i for i, start in enumerate(_ENTRY_ORDER) if start and rest.startswith(start)), 2)
    return float(head.split()[2]), rank


def _legend_below(ax, ncol: int = 1, order: bool = False) -> None:
    """The axes' legend under it (it covers no data), when anything is labelled; ``order``: by amplitude and
    kind (:func:`_entry_key`), else in drawing order."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    if order:
        pairs = sorted(zip(handles, labels, strict=True), key=lambda hl: _entry_key(hl[1]))
        handles, labels = [h for h, _ in pairs], [lb for _, lb in pairs]
    ax.legend(handles, labels, fontsize=LEGEND_FONTSIZE, loc="upper center", bbox_to_anchor=(0.5, -0.16),
              ncol=ncol, frameon=False)


def plot_sweep(results: Sequence[ProbeResult], path: str | Path | None, title: str = "", *,
               dpi: int | None = None) -> Figure:
    """omega_B against f_p (:func:`draw_probes`: stable probes with error bars joined by a guide broken at
    unstable ones, unstable probes as crosses at 0, the reasons named). Written to ``path`` (None: not written);
    returns the figure."""
    from plate_env.core.probe_table import ProbeTable

    fig, ax = new_figure(figsize=(6.5, 4.6))
    table = ProbeTable.from_results(results)
    if len(table):
        draw_probes(ax, table, guide=True, reasons=[str(r.reason) for r in results if r.unstable])
    ax.set_title(title, fontsize=9)
    _legend_below(ax, order=True)
    return _finish(fig, path, dpi)


def plot_fit(table, est, path: str | Path | None, fm=None, *, omega_n_true: float | None = None,
             dpi: int | None = None) -> Figure:
    """Two panels. Left, the data (:func:`draw_probes`) and per amplitude the curve the estimate says they follow
    (:func:`draw_model`: drawn only where the model predicts stable probes, its predicted instability as a band
    at 0). Right, omega_n (:func:`draw_posterior`): the posterior on the scale of its own 95 % interval (a log
    axis when wide), the estimate, its intervals and ``omega_n_true`` (rad/s) when known. Written to ``path``
    (None: not written); returns the figure."""
    fig, (ax, ax2) = new_figure(1, 2, figsize=(11, 4.8))
    colours = draw_probes(ax, table) if len(table) else {}
    draw_model(ax, table, est, fm, colours)
    ax.set_title(f"{len(table)} probes, {int(table.unstable.sum())} unstable", fontsize=9)
    draw_posterior(ax2, est, omega_n_true)
    _legend_below(ax, order=True)
    _legend_below(ax2, ncol=2)
    return _finish(fig, path, dpi)


def plot_curves(summaries: Sequence[AgentSummary], path: str | Path | None, *, dpi: int | None = None) -> Figure:
    """A benchmark's curves (:func:`plate_env.bench.summary.board`'s summaries): median (solid) and 90th-percentile
    (dashed) error against the probing budget, one colour per agent, the curves capped at 100 %; the median and
    its 95 % interval at each scored budget where that interval is closed. The y axis (log) reaches down to the
    smallest value drawn. Written to ``path`` (None: not written); returns the figure."""
    import math

    import numpy as np

    from plate_env.bench.report import rank

    cap = 100.0
    fig, ax = new_figure(figsize=(10.5, 4.8))
    low = 0.5
    for i, s in enumerate(rank(summaries)):
        colour = f"C{i % 10}"
        x = np.asarray(s.curve_s)
        med, p90 = (np.minimum(100 * np.asarray(v, float), cap) for v in (s.curve_median, s.curve_p90))
        ax.plot(x, med, "-", color=colour, label=f"{s.label} (area {100 * s.area.value:.1f} %)")
        ax.plot(x, p90, "--", color=colour, lw=0.8)
        # a budget's median with an open interval (no estimate for many objects: hi infinite) is left out
        pts = [(b.budget_s, [100 * v for v in (m.value, m.lo, m.hi)]) for b in s.budgets
               if math.isfinite((m := b.scores.median_error).value) and math.isfinite(m.hi)]
        if pts:
            v = np.array([p[1] for p in pts])
            ax.errorbar([p[0] for p in pts], v[:, 0], yerr=[v[:, 0] - v[:, 1], v[:, 2] - v[:, 0]], fmt="o",
                        color=colour, ms=4, capsize=3)
            drawn = np.concatenate([med, p90, v.ravel()])
        else:
            drawn = np.concatenate([med, p90])
        drawn = drawn[np.isfinite(drawn) & (drawn > 0)]
        if drawn.size:
            low = min(low, float(drawn.min()) / 1.5)
    ax.set_yscale("log")
    ax.set_ylim(max(low, 1e-3), 1.1 * cap)
    ax.set_xlabel("probing budget, simulated seconds")
    ax.set_ylabel("relative error of omega_n_hat [%] (capped at 100)")
    ax.set_title(f"{summaries[0].suite}: median (solid, 95 % CI at the budgets) and p90 (dashed)", fontsize=9)
    ax.grid(alpha=GRID_ALPHA, which="both")
    ax.legend(fontsize=LEGEND_FONTSIZE, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside: curves fill it
    return _finish(fig, path, dpi)
