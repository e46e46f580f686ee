"""Rendered frames (plate_env/env/render.py) checked by their pixels, on the atlas env (microsecond probes): the
plate's tilt between phases, the disc lying on it (or not, when unstable), the yaw marker and its trail, the probe
plot's points and unstable crosses where the probes' f_p put them, the estimate's interval, the truth only at the
end, the episode video's length, nothing drawn without a render mode, and Gymnasium's render checks."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import plate_env  # noqa: F401 - registers the environment
from plate_env.env import render
from plate_env.env.render import FPS, FRAMES_PER_PROBE, PLOT_BOX, SIDE_BOX, STRIP, TOP_CENTRE, H, W, plot_x, strip_x
from plate_env.env.rotation import PlateRotationEnv

# seed 5 of the atlas env: these probes are stable (A_p 12 deg at 12 Hz, 3 deg at 20 Hz), 38 Hz at 3 deg unstable
SEED, STABLE_12, STABLE_20, UNSTABLE_38 = 5, (12.0, 12.0), (20.0, 3.0), (38.0, 3.0)


def env_list(**kw):
    return PlateRotationEnv(physics="atlas", max_probes=6, render_mode="rgb_array_list", **kw)


def probe(env, f_a, window_s=1.0):
    out = env.step(env.encode_action(f_a[0], f_a[1], window_s))
    return out, env.render()


def mask(frame, colour, box=(0, 0, W, H)):
    """Pixels of exactly ``colour`` inside ``box`` (x0, y0, x1, y1), as a boolean image of the box."""
    x0, y0, x1, y1 = (int(v) for v in box)
    return np.all(frame[y0:y1, x0:x1] == np.array(colour, np.uint8), axis=-1)


def angle_deg(m):
    """The angle of the straight thick line a mask holds, deg, counter-clockwise on screen."""
    ys, xs = np.nonzero(m)
    assert len(xs) > 50, "no line found"
    return -math.degrees(math.atan(np.polyfit(xs, ys, 1)[0]))


@pytest.fixture(scope="module")
def episode():
    """An episode: a stable probe at 20 Hz 3 deg, a stable one at 12 Hz 12 deg, an unstable one at 38 Hz, stop."""
    env = env_list()
    env.reset(seed=SEED)
    frames = {"reset": env.render()}
    for name, f_a in (("s20", STABLE_20), ("s12", STABLE_12), ("u38", UNSTABLE_38)):
        frames[name] = probe(env, f_a)[1]
    out = env.step(env.encode_action(stop=True))
    frames["stop"] = env.render()
    rows = list(env.episode.rows)
    assert [r[4] for r in rows] == [False, False, True]  # the probes are what the tests below assume
    yield env, frames, rows, out
    env.close()


def test_frames_per_step_and_video_length(episode):
    env, frames, rows, (_, _, terminated, _, _) = episode
    assert terminated
    assert [len(frames[k]) for k in ("reset", "s20", "s12", "u38", "stop")] == [1] + [FRAMES_PER_PROBE] * 3 + [FPS]
    assert all(f.shape == (H, W, 3) and f.dtype == np.uint8 for v in frames.values() for f in v)
    assert env.metadata["render_fps"] == FPS
    total = sum(len(v) for v in frames.values())
    assert total / FPS == pytest.approx(1 / FPS + len(rows) + 1)  # a second per probe, a second to read the end
    still = PlateRotationEnv(physics="atlas", render_mode="rgb_array")
    assert still.metadata["render_fps"] == FPS / FRAMES_PER_PROBE == 1  # one frame per probe, a second each
    assert PlateRotationEnv.metadata["render_fps"] == FPS  # the class's metadata is left as it was


def test_the_plate_tilts_through_its_period_and_a_stable_disc_lies_on_it(episode):
    _, frames, rows, _ = episode
    for name, a_p in (("s12", 12.0), ("s20", 3.0)):
        quarter, three_quarters = frames[name][FRAMES_PER_PROBE // 4 - 1], frames[name][3 * FRAMES_PER_PROBE // 4 - 1]
        up = angle_deg(mask(quarter, render.PLATE, SIDE_BOX))
        down = angle_deg(mask(three_quarters, render.PLATE, SIDE_BOX))
        assert up == pytest.approx(a_p, abs=0.6) and down == pytest.approx(-a_p, abs=0.6), (name, up, down)
        disc = angle_deg(mask(quarter, render.DISC_EDGE, SIDE_BOX))
        assert disc == pytest.approx(up, abs=0.6)  # the disc follows the plate


def test_an_unstable_probe_is_marked_red_and_its_disc_leaves_the_plate(episode):
    _, frames, rows, _ = episode
    x0, y0, x1, y1 = PLOT_BOX
    plot = (x0 - 10, y0, x1 + 10, y1 + 8)  # the axes, without the legend below them
    stable, unstable = frames["s12"][-1], frames["u38"][-1]
    assert not mask(stable, render.UNSTABLE, plot).any()
    ys, xs = np.nonzero(mask(unstable, render.UNSTABLE, plot))
    assert len(xs) > 20 and abs(xs.mean() + plot[0] - plot_x(rows[2][0], (10.0, 40.0))) < 2
    assert abs(ys.mean() + plot[1] - y1) < 2  # on the axis: the camera has no omega_B for it
    assert mask(unstable, render.UNSTABLE, HEADER_BOX).sum() > 1000  # the red banner
    assert not mask(stable, render.UNSTABLE, HEADER_BOX).any()
    side = mask(unstable, render.UNSTABLE, SIDE_BOX)
    assert side.sum() > 200 and not mask(unstable, render.DISC_EDGE, SIDE_BOX).any()
    tilts = [angle_deg(mask(f, render.PLATE, SIDE_BOX)) for f in frames["u38"][5:6]]
    assert abs(angle_deg(side) - tilts[0]) > 2  # not lying on the plate


HEADER_BOX = render.HEADER


def test_the_plot_has_a_point_at_each_stable_probes_f_p_and_rings_the_current_one(episode):
    _, frames, rows, _ = episode
    x0, y0, x1, y1 = PLOT_BOX
    frame = frames["s12"][-1]
    _, xs = np.nonzero(mask(frame, render.STABLE, PLOT_BOX))
    found = sorted({round(x + x0) for x in xs})
    expected = [plot_x(r[0], (10.0, 40.0)) for r in rows[:2]]
    for x in expected:
        assert any(abs(v - x) <= 4 for v in found), x
    assert all(min(abs(v - x) for x in expected) <= 5 for v in found), (found, expected)  # nowhere else (radius 4)
    _, cx = np.nonzero(mask(frame, render.CURRENT, PLOT_BOX))
    assert abs(cx.mean() + x0 - plot_x(rows[1][0], (10.0, 40.0))) < 2  # the ring: the 12 Hz probe
    assert not mask(frames["reset"][0], render.STABLE, PLOT_BOX).any()


def test_the_yaw_marker_ends_at_the_measured_rotation_and_leaves_a_trail(episode):
    _, frames, rows, _ = episode
    cx, cy = TOP_CENTRE
    top = (cx - 100, cy - 90, cx + 100, cy + 90)
    for name, k in (("s20", 0), ("s12", 1)):
        last = frames[name][-1]  # phase 1: the plate level, so the top view is not foreshortened
        ys, xs = np.nonzero(mask(last, render.MARKER, top))
        drawn = math.degrees(math.atan2(-(ys.mean() + top[1] - cy), xs.mean() + top[0] - cx))
        yaw = sum(r[2] * r[5] for r in rows[:k + 1])
        assert abs((drawn - yaw + 180) % 360 - 180) < 4, (name, drawn, yaw % 360)
        assert mask(last, render.TRAIL[-1], top).sum() > 30  # the trail's newest part
    assert not mask(frames["u38"][-1], render.TRAIL[-1], top).any()  # no rotation measured: no trail


@pytest.fixture(scope="module")
def estimated():
    """Four stable 3-deg probes at 14-26 Hz and a stop, a frame after each: enough probes that the estimate stands
    (the episode above's two stable probes cannot place the object inside the identifiable range, so since the
    estimate contract of issue 37 its end shows a bound, not an interval)."""
    env = env_list()
    env.reset(seed=SEED)
    frames = {"reset": env.render()}
    for f in (14.0, 18.0, 22.0, 26.0):
        frames[f"s{f:g}"] = probe(env, (f, 3.0))[1]
    out = env.step(env.encode_action(stop=True))
    frames["stop"] = env.render()
    assert not any(r[4] for r in env.episode.rows)  # the probes are stable, as the test assumes
    yield env, frames, out
    env.close()


def test_the_estimate_and_its_interval_and_the_truth_only_at_the_end(estimated):
    env, frames, (_, _, _, _, info) = estimated
    x0, y, x1 = STRIP
    end = frames["stop"][-1]
    bar = mask(end, render.CI68, (x0 - 2, y - 4, x1 + 2, y + 4))
    _, xs = np.nonzero(bar)
    est = info["estimate"]
    assert est["ok"]
    lo, hi = est["omega_n_ci68_lo_rad_s"] / math.pi, est["omega_n_ci68_hi_rad_s"] / math.pi
    prior = env.omega_n_range_pi
    assert abs(xs.min() + x0 - 2 - strip_x(lo, prior)) <= 2 and abs(xs.max() + x0 - 2 - strip_x(hi, prior)) <= 2
    text = mask(end, render.CI68, (x0 - 50, y - 40, x1, y - 18))  # "omega_n_hat = ...", in the interval's colour
    assert text.sum() > 100
    truth = mask(end, render.TRUTH, (x0 - 10, y - 20, x1 + 10, y))
    _, tx = np.nonzero(truth)
    assert abs(tx.min() + x0 - 10 + 6 - strip_x(info["omega_n_true_rad_s"] / math.pi, prior)) <= 2
    for name in ("reset", "s14", "s18", "s22", "s26"):  # the truth is hidden while the episode runs
        assert not mask(frames[name][-1], render.TRUTH).any(), name
    assert not mask(frames["reset"][0], render.CI68).any()  # no probe, no estimate


def test_rendering_changes_nothing_in_the_episode():
    outs = []
    for mode in (None, "rgb_array_list"):
        env = PlateRotationEnv(physics="atlas", max_probes=4, render_mode=mode)
        env.reset(seed=SEED)
        steps = [env.step(env.encode_action(f, a, 1.0)) for f, a in (STABLE_20, STABLE_12, UNSTABLE_38, (15.0, 3.0))]
        outs.append(steps)
        env.close()
    for (o1, r1, t1, _, i1), (o2, r2, t2, _, i2) in zip(*outs, strict=True):
        assert np.array_equal(o1, o2) and r1 == r2 and t1 == t2
        i1, i2 = ({k: v for k, v in i.items() if k != "wall_s"} for i in (i1, i2))  # the one clock reading
        assert repr(i1) == repr(i2)  # every other info value, the final estimate's too


def test_no_render_mode_draws_nothing(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("drew a frame")

    monkeypatch.setattr(render, "_background", refuse)
    env = PlateRotationEnv(physics="atlas", max_probes=3)
    env.reset(seed=SEED)
    for f_a in (STABLE_20, STABLE_12, UNSTABLE_38):
        env.step(env.encode_action(*f_a, 1.0))
    assert env.render() is None and env._renderer is None
    drawing = env_list()
    with pytest.raises(AssertionError, match="drew a frame"):  # the patch does catch a frame being drawn
        drawing.reset(seed=SEED)


def test_gymnasium_render_checks_pass_for_every_mode(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")  # "human" draws into a window; no display here
    from gymnasium.utils.env_checker import check_env

    for mode in (None, "rgb_array", "rgb_array_list"):
        env = gym.make("PlateRotationAtlas-v0", max_probes=3, render_mode=mode)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            warnings.filterwarnings("ignore", message=".*out of date.*")  # the v0 id's deprecation note
            check_env(env.unwrapped)  # with the render check: every declared mode made and rendered
        env.close()


def test_save_video_writes_a_gif_at_the_render_fps(tmp_path, episode):
    from PIL import Image

    _, frames, _, _ = episode
    path = render.save_video(frames["s12"], str(tmp_path / "probe.gif"))
    with Image.open(path) as gif:
        assert gif.n_frames == FRAMES_PER_PROBE and gif.size == (W, H)
        assert gif.info["duration"] == round(1000 / FPS)
    with pytest.raises(ValueError, match="no frames"):
        render.save_video([], str(tmp_path / "none.gif"))
