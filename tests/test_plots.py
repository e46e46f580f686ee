"""The plots show the answer (issue 40 item 2): tests read the figures' axes and artists, not pixels.

Every ``--plot`` of ``fit``, ``identify``, ``sweep`` and ``bench`` goes through a plotting function that returns its
Figure; the tests capture it (wrapping the function, the PNG is still written) and check: the posterior panel's
x limits hold the 95 % interval and the interval fills most of the axis (a log axis when it is wide), the estimate
and the truth (when known) are lines on it, the model curve is absent wherever the model predicts unstable
probes, and every legend entry is an artist drawn inside the axes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.estimate import Estimate
from plate_env.identify.forward import load_forward_model


# ------------------------------------------------------------------------------------------------- helpers
def capture(monkeypatch, name: str) -> list:
    """Wrap ``plate_env.plotting.<name>`` so that each call's ``(figure returned, positional arguments, keyword
    arguments)`` is collected (the figure is still written)."""
    import plate_env.plotting as plotting

    figs, real = [], getattr(plotting, name)

    def wrapped(*a, **kw):
        fig = real(*a, **kw)
        figs.append((fig, a, kw))
        return fig

    monkeypatch.setattr(plotting, name, wrapped)
    return figs


def _visible_points(artist, ax) -> np.ndarray:
    """Mask of the line's finite points inside the axes' box (in display space: an axvline's y is in axes units)."""
    ax.get_xlim(), ax.get_ylim()  # autoscale now: the data transform reads the view limits
    x, y = (np.asarray(v, float) for v in artist.get_data())
    ok = np.isfinite(x) & np.isfinite(y)
    xy = np.zeros((x.size, 2))
    xy[ok] = artist.get_transform().transform(np.column_stack([x[ok], y[ok]]))
    box = ax.bbox
    eps = 1e-6
    inside = ((xy[:, 0] >= box.x0 - eps) & (xy[:, 0] <= box.x1 + eps) & (xy[:, 1] >= box.y0 - eps)
              & (xy[:, 1] <= box.y1 + eps))
    return ok & inside


def draws_something(artist, ax) -> bool:
    """Whether ``artist`` puts ink inside ``ax``: a line with markers one visible point, a line without markers
    two neighbouring visible points (a lone point of a plain line is invisible), a patch (a band) overlapping the
    x view, an errorbar container its data line."""
    from matplotlib.container import ErrorbarContainer
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    if isinstance(artist, ErrorbarContainer):
        return draws_something(artist.lines[0], ax)
    if isinstance(artist, Line2D):
        vis = _visible_points(artist, ax)
        if artist.get_marker() not in (None, "None", "", " ", "none"):
            return bool(vis.any())
        return artist.get_linestyle() not in ("None", "", " ") and bool((vis[1:] & vis[:-1]).any())
    if isinstance(artist, Patch):
        xs = artist.get_patch_transform().transform(artist.get_path().vertices)[:, 0]  # data x of a band
        (x0, x1) = sorted(ax.get_xlim())
        return xs.size > 0 and xs.max() >= x0 and xs.min() <= x1 and xs.max() > xs.min()
    raise AssertionError(f"unexpected legend artist {artist!r}")


def assert_every_legend_entry_drawn(ax) -> list[str]:
    """Each label in the axes' legend belongs to an artist of the axes that draws inside it; returns the labels."""
    legend = ax.get_legend()
    labels = [t.get_text() for t in legend.get_texts()] if legend is not None else []
    artists = list(ax.lines) + list(ax.patches) + list(ax.containers)
    for label in labels:
        owners = [a for a in artists if a.get_label() == label]
        assert owners, f"legend entry {label!r} has no artist on the axes"
        assert any(draws_something(a, ax) for a in owners), f"legend entry {label!r} is listed but draws nothing"
    return labels


def vlines(ax) -> dict[str, float]:
    """The vertical lines (axvline) of ``ax``: label -> x."""
    out = {}
    for ln in ax.lines:
        x, y = ln.get_data()
        if len(x) == 2 and x[0] == x[1] and ln.get_transform() is not ax.transData:
            out[str(ln.get_label())] = float(x[0])
    return out


def assert_window_shows_interval(ax, est: Estimate) -> None:
    """The x limits contain the 95 % interval (pi rad/s) and it fills at least 60 % of the axis in the axis's own
    scale; the estimate is a line inside."""
    lo, hi = (v / math.pi for v in est.omega_n_ci95)
    x0, x1 = ax.get_xlim()
    assert x0 <= lo and hi <= x1, f"x axis {x0:g}-{x1:g} pi does not hold the 95 % interval {lo:g}-{hi:g} pi"
    scale = np.log if ax.get_xscale() == "log" else (lambda v: v)
    share = (scale(hi) - scale(lo)) / (scale(x1) - scale(x0))
    assert share >= 0.6, f"the 95 % interval {lo:g}-{hi:g} pi fills {share:.0%} of the axis {x0:g}-{x1:g} pi"
    est_lines = [x for label, x in vlines(ax).items() if label.startswith("estimate")]
    assert est_lines and math.isclose(est_lines[0], est.omega_n / math.pi, rel_tol=1e-9)


def model_curves(ax) -> dict[str, object]:
    return {str(ln.get_label()): ln for ln in ax.lines if "at the estimate" in str(ln.get_label())}


# ------------------------------------------------------------------- the repro cases of the issue, end to end
def test_fit_plot_of_a_20pi_point_mass_sweep_shows_the_interval_and_no_curve_where_unstable(tmp_path, monkeypatch,
                                                                                           capsys):
    """`sweep` a 20pi point-mass disc (the point-mass atlas physics, fast) over 12-34 Hz at 3 deg, `fit --plot`:
    the posterior axis (0-45,000 pi before) is the 95 % interval's, logarithmic (the uncalibrated lab interval
    spans a factor ~500); the model curve is absent wherever the model predicts unstable probes (it rose to
    600 deg/s through 30-34 Hz before)."""
    from plate_env.cli import main
    from plate_env.identify.inference import predicted_curve

    csv = tmp_path / "s.csv"
    assert main(["sweep", "--physics", "atlas", "--omega-n", "20pi", "--freqs", "12:34:2", "--amp", "3",
                 "--csv", str(csv), "--no-progress"]) == 0
    figs = capture(monkeypatch, "plot_fit")
    assert main(["fit", str(csv), "--amp", "3", "--plot", str(tmp_path / "fit.png")]) == 0
    out = capsys.readouterr().out
    assert out.index("omega_n_hat") < out.index("plot:")  # the result is printed before the plot is made
    assert (tmp_path / "fit.png").stat().st_size > 5000
    fig, (table, est, _, fm), kw = figs[0]  # the figure, and the probes, estimate and forward model it drew
    data, post = fig.axes[:2]
    assert est.ok and est.forward == fm.name == "lab" and kw.get("omega_n_true") is None  # a CSV knows no truth
    assert est.omega_n_ci95[1] / est.omega_n_ci95[0] > 100  # the wide interval of the issue
    assert post.get_xscale() == "log"
    assert_window_shows_interval(post, est)
    assert_every_legend_entry_drawn(post)
    assert_every_legend_entry_drawn(data)

    (curve,) = model_curves(data).values()
    f, y = (np.asarray(v, float) for v in curve.get_data())
    pred = predicted_curve(fm, est, f, 3.0)
    member = next(m for m in fm.members if m.label == pred.label)
    mean, _, p_un = member.atlas.predict(f, 3.0, est.omega_n, est.alpha)  # the atlas read directly
    unstable = p_un >= 0.5
    assert unstable.any() and (~unstable).any()
    assert np.isnan(y[unstable]).all(), "the model curve is drawn where the model predicts unstable probes"
    np.testing.assert_allclose(y[~unstable], mean[~unstable], rtol=1e-9)
    # the symptom: every probe at 30-34 Hz was unstable and the curve rose through them
    bad = table.unstable & (table.f_p_hz >= 30)
    assert bad.sum() == 3
    assert np.isnan(y[f > 30.2]).all()
    # the predicted instability is drawn instead: a band at omega_B = 0 over the same frequencies
    (band,) = [ln for ln in data.lines if "model predicts unstable" in str(ln.get_label())]
    fb, yb = (np.asarray(v, float) for v in band.get_data())
    np.testing.assert_array_equal(np.isfinite(yb), unstable)
    assert np.all(yb[unstable] == 0.0)


def test_identify_plot_marks_the_truth_and_draws_both_amplitudes_curves(tmp_path, monkeypatch, capsys):
    """`identify --physics atlas --omega-n 20pi --seed 2 --plot`: the episode probes at 3 and 12 deg (one probe at
    12 deg: its curve was a zero-length line listed in the legend); the true omega_n printed is a line on the
    narrow (linear) posterior axis."""
    from plate_env.cli import main

    figs = capture(monkeypatch, "plot_fit")
    assert main(["identify", "--physics", "atlas", "--omega-n", "20pi", "--seed", "2", "--plot",
                 str(tmp_path / "run.png")]) == 0
    out = capsys.readouterr().out
    assert "true        = 62.83 rad/s (20pi)" in out and out.index("true ") < out.index("plot:")
    fig, (_, est, _, _), kw = figs[0]
    assert kw["omega_n_true"] == pytest.approx(20 * math.pi)
    data, post = fig.axes[:2]
    amps = sorted({lb.split(":")[0] for lb in assert_every_legend_entry_drawn(data)})
    assert amps == ["A_p = 12 deg", "A_p = 3 deg"], f"this episode was chosen for its two amplitudes, got {amps}"
    assert set(model_curves(data)) == {"A_p = 3 deg: tilelink/pointmass at the estimate",
                                       "A_p = 12 deg: tilelink/pointmass at the estimate"}
    assert post.get_xscale() == "linear"
    assert_window_shows_interval(post, est)
    truth = [x for label, x in vlines(post).items() if label.startswith("true")]
    assert truth == [pytest.approx(20.0)]
    x0, x1 = post.get_xlim()
    assert x0 < 20.0 < x1
    assert_every_legend_entry_drawn(post)


# ----------------------------------------------------------------------------------------- the functions
def _sweep(omega_n: float, a_p_deg: float, f: np.ndarray) -> ProbeTable:
    """The point-mass model's own mean at the object (alpha 40 deg), its instability where p_unstable >= 0.5."""
    m = load_forward_model("tilelink/pointmass").members[0]
    mu, _, p = m.atlas.predict(f, a_p_deg, omega_n, math.radians(40))
    un = p >= 0.5
    return ProbeTable.from_arrays(f, a_p_deg, np.where(un, 0.0, mu), np.where(un, 0.0, 0.5), un)


def test_a_second_amplitude_probed_once_gets_a_visible_curve_over_the_probed_range():
    """One probe at 12 deg: its model curve spans every probed frequency (not the zero-length range of its one
    probe) where the model predicts stable probes, and its legend entries are drawn."""
    from plate_env.identify.inference import identify_atlas
    from plate_env.plotting import plot_fit

    fm = load_forward_model("tilelink/pointmass")
    t = ProbeTable.concat(_sweep(10 * math.pi, 3.0, np.arange(14.0, 30.0, 1.0)),
                          _sweep(10 * math.pi, 12.0, np.array([13.0])))
    est = identify_atlas(t, fm)
    assert est.ok
    fig = plot_fit(t, est, None, fm, omega_n_true=10 * math.pi)
    data = fig.axes[0]
    labels = assert_every_legend_entry_drawn(data)
    assert "A_p = 12 deg: tilelink/pointmass at the estimate" in labels
    ln = model_curves(data)["A_p = 12 deg: tilelink/pointmass at the estimate"]
    f = np.asarray(ln.get_data()[0], float)
    assert f.min() == t.f_p_hz.min() and f.max() == t.f_p_hz.max()


def _estimate(value: float, ci68: tuple[float, float], ci95: tuple[float, float], ok: bool = True, **kw) -> Estimate:
    return Estimate(ok=ok, method="lorentz", omega_n=value, omega_n_ci68=ci68, omega_n_ci95=ci95, **kw)


@pytest.mark.parametrize("ci95, log", [((0.9 * math.pi * 20, 1.1 * math.pi * 20), False),
                                       ((2.6, 1390.0), True),
                                       ((0.0, 229.0), False)])  # `fit --method lorentz`: was a log axis from 1e-9 pi
def test_posterior_window_is_the_intervals_scale(ci95, log):
    """A Lorentz estimate (no posterior grid): the window is its 95 % interval, linear when narrow, log when wide;
    the 68 % and 95 % bands and the estimate are drawn; a truth outside the interval widens the window to it."""
    from plate_env.plotting import draw_posterior, new_figure, posterior_window

    mid = math.sqrt(ci95[0] * ci95[1]) or ci95[1] / 3
    est = _estimate(mid, (mid * 0.99, mid * 1.01), ci95)
    lo, hi, is_log = posterior_window(est)
    assert is_log is log and lo <= ci95[0] and ci95[1] < hi and (lo < ci95[0] or lo == 0.0)
    fig, ax = new_figure()
    draw_posterior(ax, est)
    _legend(ax)
    assert ax.get_xscale() == ("log" if log else "linear")
    assert_window_shows_interval(ax, est)
    labels = assert_every_legend_entry_drawn(ax)
    assert any(lb.startswith("68 %") for lb in labels) and any(lb.startswith("95 %") for lb in labels)
    far = 3 * ci95[1]
    lo2, hi2, _ = posterior_window(est, far)
    assert hi2 >= far and lo2 <= ci95[0]
    fig, ax = new_figure()
    draw_posterior(ax, est, far)
    assert [x for label, x in vlines(ax).items() if label.startswith("true")] == [pytest.approx(far / math.pi)]
    assert ax.get_xlim()[1] > far / math.pi


def _legend(ax) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend()


def test_a_bound_and_no_estimate_show_what_there_is():
    """A bound: the window runs from a third of it up (above), with the bound a line; no estimate and no
    posterior: no estimate line, the title says why."""
    from plate_env.plotting import draw_posterior, new_figure, posterior_window

    est = Estimate(ok=False, method="lorentz", reason="3 stable probes: too few", bound=None)
    fig, ax = new_figure()
    draw_posterior(ax, est, 20 * math.pi)
    assert ax.get_title().startswith("no estimate: 3 stable probes")
    assert not [lb for lb in vlines(ax) if lb.startswith("estimate")]
    assert ax.get_xlim()[0] < 20 < ax.get_xlim()[1]
    b = Estimate(ok=False, method="lorentz", reason="bound", bound=("below", 5.0))
    lo, hi, log = posterior_window(b)
    assert log and lo < 0.5 and 15.0 < hi < 45.0  # a decade below the bound to three times it, padded
    fig, ax = new_figure()
    draw_posterior(ax, b)
    assert [x for lb, x in vlines(ax).items() if lb.startswith("bound")] == [pytest.approx(5.0 / math.pi)]


def test_sweep_plot_breaks_its_guide_at_unstable_probes_and_draws_every_entry(tmp_path, monkeypatch, capsys):
    from plate_env.cli import main

    figs = capture(monkeypatch, "plot_sweep")
    assert main(["sweep", "--physics", "atlas", "--omega-n", "20pi", "--freqs", "12:34:2", "--amp", "3",
                 "--plot", str(tmp_path / "sweep.png"), "--no-progress"]) == 0
    capsys.readouterr()
    ax = figs[0][0].axes[0]
    labels = assert_every_legend_entry_drawn(ax)
    assert any("unstable probes (slipped)" in lb for lb in labels)
    (guide,) = [ln for ln in ax.lines if ln.get_label().startswith("_") and ln.get_linestyle() == "-"
                and ln.get_marker() in ("None", None, "")]
    (crosses,) = [ln for ln in ax.lines if "unstable probes" in str(ln.get_label())]
    f, y = (np.asarray(v, float) for v in guide.get_data())
    fx = np.asarray(crosses.get_data()[0], float)
    assert fx.size > 0 and np.isnan(y[np.isin(f, fx)]).all()  # no line through an unstable probe
    assert np.isfinite(y[~np.isin(f, fx)]).all()


def test_bench_plot_reaches_down_to_its_smallest_value(tmp_path, monkeypatch, capsys):
    """`bench --plot`: the log y axis (fixed at 0.5-110 % before) holds every error drawn, a 95 % interval's lower
    end below 0.5 % included; every legend entry is a curve drawn."""
    from plate_env.cli import main

    figs = capture(monkeypatch, "plot_curves")
    assert main(["bench", "--suite", "atlas-v0", "--agent", "bayes", "grid", "--limit", "3", "--no-cache",
                 "--no-progress", "--plot", str(tmp_path / "bench.png")]) == 0
    capsys.readouterr()
    ax = figs[0][0].axes[0]
    assert_every_legend_entry_drawn(ax)
    ys = np.concatenate([np.asarray(ln.get_data()[1], float) for ln in ax.lines]
                        + [np.asarray(seg)[:, :, 1].ravel() for c in ax.collections
                           for seg in [c.get_segments()] if len(seg)])
    ys = ys[np.isfinite(ys) & (ys > 0)]
    assert ys.min() < 0.5, "this case was chosen for an error bar reaching below 0.5 %"
    y0, y1 = ax.get_ylim()
    assert y0 <= ys.min() and ys.max() <= y1


def test_only_an_atlas_estimate_has_a_model_curve():
    """predicted_curve reads the atlas at an estimate that carries its posterior: a Lorentz reading with the same
    omega_n and alpha (no posterior) and no estimate get no curve; the atlas estimate of the same probes gets one."""
    import dataclasses

    from plate_env.core.probe_table import ProbeTable
    from plate_env.identify import identify
    from plate_env.identify.forward import load_forward_model
    from plate_env.identify.inference import predicted_curve

    fm = load_forward_model("tilelink/pointmass")
    atlas = fm.members[0].atlas
    f = np.arange(12.0, 30.5, 1.0)
    mean, _, p_un = atlas.predict(f, 3.0, 20 * np.pi, np.radians(45.0))
    stable = p_un < 0.5
    n = int(stable.sum())
    table = ProbeTable.from_arrays(f[stable], 3.0, mean[stable], np.full(n, 0.5), np.zeros(n, bool))
    est = identify(table, forward="tilelink/pointmass")
    assert est.ok and est.posterior is not None and predicted_curve(fm, est, f, 3.0) is not None
    lorentz = dataclasses.replace(est, method="lorentz", posterior=None)
    assert lorentz.alpha is not None and predicted_curve(fm, lorentz, f, 3.0) is None
    assert predicted_curve(fm, dataclasses.replace(est, ok=False), f, 3.0) is None
