"""What a rendered frame shows and how it is drawn (Pillow, no GUI), and a window for ``render_mode="human"``.

A frame (``H`` x ``W`` RGB, uint8) has four parts:

* header: the probe count, the current probe's f_p, A_p, window and the camera's omega_B (or UNSTABLE, in red);
* top view (upper left): the disc on the plate with its yaw marker and the trail of the marker over the probe;
* side view (lower left): the plate tilted by A_p sin(2 pi phase), drawn to scale, with the disc lying on it
  (an unstable disc is drawn red, lifted and out of line: it did not follow the plate);
* the probe history (right): omega_B against f_p over the env's band (stable probes blue with their standard
  error, unstable ones as red crosses on the axis, the current one ringed) and under it the current estimate of
  omega_n with its 68 % and 95 % intervals on the prior's log scale (the true omega_n only once the env reveals it).

An animation of one probe (:func:`probe_frames`) is drawn from the probe's known motion, never re-simulated: the
plate goes through one period of its tilt while the disc turns by the measured omega_B times the window (slow
motion: ``FRAMES_PER_PROBE`` frames, a second of video at ``FPS``). The parts that do not move are drawn once per
probe (:func:`_background`), the plate and the disc once per frame.
"""

from __future__ import annotations

import importlib.util
import math
import os
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

H, W = 360, 640
#: Frames of one probe's animation and the frame rate they play at: a probe is one second of video.
FRAMES_PER_PROBE = 20
FPS = 20

BACKGROUND = (246, 246, 246)
INK = (30, 30, 30)
GREY = (150, 150, 150)
PLATE_TOP = (200, 200, 210)
PLATE = (70, 70, 95)  # the plate's edge in the side view (tests find it by this colour)
GUIDE = (200, 200, 225)
DISC = (235, 190, 60)
DISC_EDGE = (150, 110, 20)
MARKER = (120, 50, 10)
TRAIL = ((253, 224, 200), (250, 190, 140), (245, 150, 80), (235, 110, 30), (220, 80, 0))
STABLE = (40, 90, 200)
UNSTABLE = (220, 30, 30)
CURRENT = (255, 140, 0)
CI68 = (30, 150, 60)
CI95 = (170, 215, 175)
TRUTH = (160, 0, 160)

#: Regions (x0, y0, x1, y1) in pixels: the header, the top view's centre and radius, the side view's pivot and half
#: length, the probe plot's axes box and the estimate strip's axis (its y is the bars' centre).
HEADER = (0, 0, W, 46)
TOP_CENTRE, DISC_RADIUS = (150, 142), 78
SIDE_PIVOT, PLATE_HALF = (150, 300), 130
SIDE_BOX = (8, 244, 296, 356)
PLOT_BOX = (360, 70, 626, 236)
STRIP = (360, 322, 626)


@dataclass(frozen=True)
class Scene:
    """What a frame shows: the env's state after a probe (or after reset), in the env's units.

    ``rows``: the probes so far as the env's table holds them, each (f_p Hz, A_p deg, omega_B deg/s, its standard
    error deg/s, unstable, window s); the last is the current probe. ``estimate``: None (no estimate yet) or
    (omega_n_hat, ci68 lo, ci68 hi, ci95 lo, ci95 hi), all in pi rad/s; ``reason``: why there is none.
    ``truth_pi``: the hidden omega_n in pi rad/s, only when the env reveals it (episode over or ``reveal_truth``).
    """

    rows: tuple = ()
    max_probes: int = 30
    f_band_hz: tuple[float, float] = (10.0, 40.0)
    omega_n_range_pi: tuple[float, float] = (3.5, 33.0)
    sim_s: float = 0.0
    estimate: tuple[float, float, float, float, float] | None = None
    reason: str = "no probes"
    truth_pi: float | None = None
    done: bool = False

    def yaw_start_deg(self) -> float:
        """The disc's yaw when the current probe starts: the measured rotations of the probes before it, deg."""
        return float(sum(r[2] * r[5] for r in self.rows[:-1]))

    def turn_deg(self) -> float:
        """The current probe's measured rotation: omega_B times its window, deg (0 without a probe)."""
        return float(self.rows[-1][2] * self.rows[-1][5]) if self.rows else 0.0


@lru_cache(maxsize=4)
def _font(size: int):
    """DejaVu Sans (shipped with matplotlib, found without importing it) at ``size`` px, else Pillow's default."""
    from PIL import ImageFont

    spec = importlib.util.find_spec("matplotlib")
    if spec is not None and spec.submodule_search_locations:
        path = os.path.join(spec.submodule_search_locations[0], "mpl-data", "fonts", "ttf", "DejaVuSans.ttf")
        if os.path.exists(path):
            return ImageFont.truetype(path, size)
    return ImageFont.load_default(size)


def plot_x(f_hz: float, band: tuple[float, float]) -> float:
    """The x pixel of f_p (Hz) in the probe plot."""
    x0, _, x1, _ = PLOT_BOX
    return x0 + (f_hz - band[0]) / (band[1] - band[0]) * (x1 - x0)


def strip_x(omega_pi: float, prior: tuple[float, float]) -> float:
    """The x pixel of omega_n (pi rad/s) on the estimate strip (log scale over the prior's range), clipped to it."""
    x0, _, x1 = STRIP
    u = (math.log(max(omega_pi, 1e-9)) - math.log(prior[0])) / (math.log(prior[1]) - math.log(prior[0]))
    return x0 + min(max(u, 0.0), 1.0) * (x1 - x0)


def _y_top(rows) -> float:
    """The probe plot's omega_B range, 0 to this (deg/s): a round number above every probe's omega_B + stderr."""
    top = max([r[2] + r[3] for r in rows] + [100.0]) * 1.1
    step = 10 ** math.floor(math.log10(top)) / 2
    return math.ceil(top / step) * step


def _header(draw, scene: Scene) -> None:
    big, small = _font(15), _font(13)
    n = len(scene.rows)
    if not n:
        draw.text((10, 6), f"probe 0 / {scene.max_probes}: no probe yet", font=big, fill=INK)
        draw.text((10, 26), "an action picks f_p, A_p and the window, or stops", font=small, fill=GREY)
        return
    f, a, omega, se, unstable, window = scene.rows[-1]
    draw.text((10, 6), f"probe {n} / {scene.max_probes}    f_p {f:.1f} Hz    A_p {a:.0f}°    window {window:.2f} s"
              f"    sim {scene.sim_s:.1f} s", font=big, fill=INK)
    if unstable:
        draw.rectangle((6, 25, 440, 43), fill=UNSTABLE)
        draw.text((10, 26), "UNSTABLE: the disc did not follow the plate; no ω_B", font=small, fill=(255, 255, 255))
    else:
        text = f"ω_B = {omega:.0f} ± {se:.1f} deg/s (camera);  this probe turned it {omega * window:+.0f}°"
        draw.text((10, 26), text, font=small, fill=STABLE)
    if scene.done:
        draw.text((540, 26), "episode over", font=small, fill=INK)


def _plot(draw, scene: Scene) -> None:
    small = _font(11)
    x0, y0, x1, y1 = PLOT_BOX
    band, rows = scene.f_band_hz, scene.rows
    top = _y_top(rows)

    def y_of(w):
        return y1 - w / top * (y1 - y0)

    draw.text((x0 - 46, y0 - 20), "probes: ω_B (deg/s) against f_p (Hz)", font=_font(13), fill=INK)
    for k in range(1, 5):
        draw.line((x0, y_of(top * k / 4), x1, y_of(top * k / 4)), fill=(228, 228, 228))
    draw.rectangle((x0, y0, x1, y1), outline=GREY)
    draw.text((x0 - 6, y0), f"{top:.0f}", font=small, fill=INK, anchor="rt")
    draw.text((x0 - 6, y1), "0", font=small, fill=INK, anchor="rb")
    for f in (band[0], (band[0] + band[1]) / 2, band[1]):
        draw.text((plot_x(f, band), y1 + 4), f"{f:g}", font=small, fill=INK, anchor="mt")
    for k, (f, _, omega, se, unstable, _) in enumerate(rows):
        x = plot_x(f, band)
        if unstable:  # a red cross on the axis: the camera has no omega_B for it
            draw.line((x - 6, y1 - 6, x + 6, y1 + 6), fill=UNSTABLE, width=3)
            draw.line((x - 6, y1 + 6, x + 6, y1 - 6), fill=UNSTABLE, width=3)
            y = y1
        else:
            y = y_of(omega)
            if se > 0:
                draw.line((x, y_of(omega - se), x, y_of(omega + se)), fill=STABLE, width=1)
            draw.ellipse((x - 4, y - 4, x + 4, y + 4), fill=STABLE)
        if k == len(rows) - 1:
            draw.ellipse((x - 9, y - 9, x + 9, y + 9), outline=CURRENT, width=2)
    draw.ellipse((x0 + 4, y1 + 22, x0 + 12, y1 + 30), fill=STABLE)
    draw.text((x0 + 16, y1 + 20), "stable", font=small, fill=INK)
    lx = x0 + 70
    draw.line((lx, y1 + 21, lx + 9, y1 + 30), fill=UNSTABLE, width=3)
    draw.line((lx, y1 + 30, lx + 9, y1 + 21), fill=UNSTABLE, width=3)
    draw.text((lx + 14, y1 + 20), "unstable", font=small, fill=INK)
    draw.ellipse((lx + 84, y1 + 20, lx + 96, y1 + 32), outline=CURRENT, width=2)
    draw.text((lx + 100, y1 + 20), "this probe", font=small, fill=INK)


def _strip(draw, scene: Scene) -> None:
    x0, y, x1 = STRIP
    prior = scene.omega_n_range_pi
    est = scene.estimate
    if est is None:
        text = "no estimate yet" if scene.reason == "no probes" else f"no estimate: {scene.reason}"
        draw.text((x0 - 46, y - 36), text[:64], font=_font(13), fill=INK)
    else:
        draw.text((x0 - 46, y - 36), f"ω̂_n = {est[0]:.2f}π rad/s   68 %: {est[1]:.2f}π – {est[2]:.2f}π",
                  font=_font(13), fill=CI68)
    draw.line((x0, y, x1, y), fill=GREY, width=1)
    for w in prior:
        draw.line((strip_x(w, prior), y - 4, strip_x(w, prior), y + 4), fill=GREY)
        draw.text((strip_x(w, prior), y + 9), f"{w:g}π", font=_font(11), fill=INK, anchor="mt")
    draw.text((x0 - 46, y - 7), "ω_n", font=_font(12), fill=INK)
    if est is not None:
        draw.rectangle((strip_x(est[3], prior), y - 3, strip_x(est[4], prior), y + 3), fill=CI95)
        draw.rectangle((strip_x(est[1], prior), y - 6, strip_x(est[2], prior), y + 6), fill=CI68)
        xm = strip_x(est[0], prior)
        draw.rectangle((xm - 1, y - 10, xm + 1, y + 10), fill=(10, 80, 30))
    if scene.truth_pi is not None:
        xt = strip_x(scene.truth_pi, prior)
        draw.polygon(((xt, y - 8), (xt - 6, y - 18), (xt + 6, y - 18)), fill=TRUTH)
        draw.text((xt + 8, y - 22), f"true {scene.truth_pi:.2f}π", font=_font(11), fill=TRUTH)


def _background(scene: Scene):
    """The parts of a frame that stay put while a probe plays (a Pillow image)."""
    from PIL import Image, ImageDraw

    img = Image.new("RGB", (W, H), BACKGROUND)
    draw = ImageDraw.Draw(img)
    _header(draw, scene)
    cx, cy = TOP_CENTRE
    draw.rectangle((cx - 120, cy - 90, cx + 120, cy + 90), fill=PLATE_TOP)
    draw.text((cx - 116, cy - 88), "top view", font=_font(11), fill=INK)
    draw.rectangle(SIDE_BOX, outline=(225, 225, 225))
    draw.text((SIDE_BOX[0] + 4, SIDE_BOX[1] + 2), "side view, tilt to scale", font=_font(11), fill=INK)
    a_p = scene.rows[-1][1] if scene.rows else 0.0
    px, py = SIDE_PIVOT
    for sgn in (1, -1):  # the tilt's extremes
        t = math.radians(sgn * a_p)
        draw.line((px - PLATE_HALF * math.cos(t), py + PLATE_HALF * math.sin(t),
                   px + PLATE_HALF * math.cos(t), py - PLATE_HALF * math.sin(t)), fill=GUIDE, width=1)
    _plot(draw, scene)
    _strip(draw, scene)
    return img


def _moving(draw, scene: Scene, phase: float, progress: float) -> None:
    """The plate and the disc at ``phase`` (periods of the plate's tilt) and ``progress`` (share of the probe's
    rotation done, 0..1)."""
    unstable = bool(scene.rows and scene.rows[-1][4])
    a_p = scene.rows[-1][1] if scene.rows else 0.0
    tilt = math.radians(a_p * math.sin(2 * math.pi * phase))
    # top view: the disc foreshortened by the tilt (about the horizontal axis), its marker at the yaw reached
    cx, cy = TOP_CENTRE
    r, ry = DISC_RADIUS, DISC_RADIUS * math.cos(tilt)
    draw.ellipse((cx - r, cy - ry, cx + r, cy + ry), fill=UNSTABLE if unstable else DISC,
                 outline=DISC_EDGE, width=2)
    turn = scene.turn_deg() * progress
    yaw = scene.yaw_start_deg() + turn
    span = min(abs(turn), 330.0)
    if span > 0:  # the trail: the marker tip's path over the probe so far (its last 330 deg), fading with age
        sgn = 1.0 if turn > 0 else -1.0
        rt = 0.82 * r
        for k, colour in enumerate(TRAIL):
            a0, a1 = yaw - sgn * span * (1 - k / len(TRAIL)), yaw - sgn * span * (1 - (k + 1) / len(TRAIL))
            lo, hi = sorted((a0, a1))
            # Pillow's angles run clockwise on screen; the yaw counter-clockwise
            draw.arc((cx - rt, cy - rt * math.cos(tilt), cx + rt, cy + rt * math.cos(tilt)), -hi, -lo,
                     fill=colour, width=6)
    yr = math.radians(yaw)
    draw.line((cx, cy, cx + r * math.cos(yr), cy - ry * math.sin(yr)), fill=MARKER, width=4)
    draw.text((cx + 116, cy - 88), f"yaw {yaw:+.0f}°", font=_font(12), fill=INK, anchor="rt")
    # side view: the plate through its pivot at the tilt, the disc lying on it (or, unstable, lifted out of line)
    px, py = SIDE_PIVOT
    d = (math.cos(tilt), -math.sin(tilt))
    n = (-math.sin(tilt), -math.cos(tilt))  # the plate's upward normal on screen
    draw.line((px - PLATE_HALF * d[0], py - PLATE_HALF * d[1], px + PLATE_HALF * d[0], py + PLATE_HALF * d[1]),
              fill=PLATE, width=7)
    half = r * 0.95
    if unstable:
        hop = 22 + 10 * abs(math.sin(4 * math.pi * phase))
        c = (px + n[0] * hop, py + n[1] * hop - 8)
        wrong = -1.6 * tilt + 0.12
        dd = (math.cos(wrong), -math.sin(wrong))
        colour = UNSTABLE
    else:
        c, dd, colour = (px + 7 * n[0], py + 7 * n[1]), d, DISC_EDGE
    draw.line((c[0] - half * dd[0], c[1] - half * dd[1], c[0] + half * dd[0], c[1] + half * dd[1]),
              fill=colour, width=5)


def draw_frame(scene: Scene, phase: float = 0.25, progress: float = 1.0, background=None) -> np.ndarray:
    """One frame (H x W x 3, uint8) of ``scene`` at ``phase`` (periods of the tilt; 0.25: the plate at +A_p) and
    ``progress`` (share of the probe's measured rotation done, 0..1). ``background``: :func:`_background` of the
    scene, when drawing many frames of it."""
    from PIL import ImageDraw

    img = (background if background is not None else _background(scene)).copy()
    _moving(ImageDraw.Draw(img), scene, phase, progress)
    return np.asarray(img, dtype=np.uint8)


def probe_frames(scene: Scene, n: int = FRAMES_PER_PROBE) -> list[np.ndarray]:
    """The current probe played in ``n`` frames: the plate through one period of its tilt, the disc turning by the
    probe's measured rotation (from the probe's motion and the camera's omega_B, not re-simulated)."""
    if n < 1:
        raise ValueError(f"n = {n} frames: need at least 1")
    background = _background(scene)
    return [draw_frame(scene, (k + 1) / n, (k + 1) / n, background) for k in range(n)]


def save_video(frames: list[np.ndarray], path: str, fps: float = FPS) -> str:
    """Write ``frames`` as an animated GIF (Pillow) playing at ``fps``; returns ``path``."""
    from PIL import Image

    if not frames:
        raise ValueError("save_video: no frames")
    if not fps > 0:
        raise ValueError(f"fps = {fps}: must be > 0")
    images = [Image.fromarray(f) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0,
                   optimize=False)
    return path


class Renderer:
    """The env's rendering, made on its first frame (never with ``render_mode=None``).

    ``rgb_array``: :meth:`render` draws the state after the last step (one frame per step). ``rgb_array_list``:
    :meth:`reset` and :meth:`step` collect frames (one after reset, ``FRAMES_PER_PROBE`` per probe, ``FPS`` copies
    of the last state when the episode ends: a second to read the result) and :meth:`render` hands over those
    collected since its last call (Gymnasium's convention). ``human``: the same frames shown in a matplotlib window
    at ``FPS`` as they come.
    """

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.frames: list[np.ndarray] = []
        self.window = None

    def reset(self, scene: Scene) -> None:
        self.frames = [draw_frame(scene, 0.0, 0.0)]
        self._show()

    def step(self, scene: Scene, probed: bool, over: bool) -> None:
        if probed:
            self.frames.extend(probe_frames(scene))
        if over:
            self.frames.extend([draw_frame(scene, 0.0, 1.0)] * FPS)
        self._show()

    def render(self, scene: Scene) -> np.ndarray | list[np.ndarray] | None:
        if self.mode == "rgb_array":
            return draw_frame(scene)
        if self.mode == "rgb_array_list":
            frames, self.frames = self.frames, []
            return frames
        if self.window is None and not self.frames:
            self.frames = [draw_frame(scene)]
        self._show()
        return None

    def _show(self) -> None:
        if self.mode != "human":
            return
        for frame in self.frames:
            self.window = show(frame, self.window, 1.0 / FPS)
        self.frames = []

    def close(self) -> None:
        if self.window is not None:
            close_window(self.window)
            self.window = None


def show(frame: np.ndarray, window=None, pause_s: float = 0.001):
    """Show a frame in a matplotlib window (needs a display); returns the window handle."""
    import matplotlib.pyplot as plt

    if window is None:
        plt.ion()
        fig, ax = plt.subplots(figsize=(W / 100, H / 100), dpi=100)
        ax.axis("off")
        fig.subplots_adjust(0, 0, 1, 1)
        window = (fig, ax.imshow(frame))
    else:
        window[1].set_data(frame)
    window[0].canvas.draw_idle()
    plt.pause(pause_s)
    return window


def close_window(window) -> None:
    import matplotlib.pyplot as plt

    plt.close(window[0])

