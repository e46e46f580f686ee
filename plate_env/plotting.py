"""Plots for sweeps and fits (matplotlib, imported only when a plot is asked for)."""

from __future__ import annotations

from collections.abc import Sequence

from plate_env.physics.base import ProbeResult


def plot_sweep(results: Sequence[ProbeResult], path: str, title: str = "") -> None:
    """omega_B against f_p; stable probes with error bars, unstable ones as crosses at the axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
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
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
