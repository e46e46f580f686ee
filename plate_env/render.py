"""Drawing the plate and the disc for ``render_mode="rgb_array"`` (plain numpy, no GUI) and a window for "human"."""

from __future__ import annotations

import math

import numpy as np

H, W = 240, 480


def _disc(img, cx, cy, r, color):
    yy, xx = np.mgrid[0:H, 0:W]
    img[(xx - cx) ** 2 + (yy - cy) ** 2 <= r * r] = color


def _line(img, x0, y0, x1, y1, color, width=2):
    n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
    for t in np.linspace(0.0, 1.0, n):
        x, y = int(round(x0 + t * (x1 - x0))), int(round(y0 + t * (y1 - y0)))
        img[max(0, y - width // 2): y + width // 2 + 1, max(0, x - width // 2): x + width // 2 + 1] = color


def draw_scene(result, obj) -> np.ndarray:
    """An RGB image (H x W x 3, uint8): left, the plate seen from above with the disc at its last yaw and centre;
    right, the plate seen along its axis, tilted by its amplitude, with the disc on it."""
    img = np.full((H, W, 3), 245, dtype=np.uint8)
    scale = 2.2  # pixels per mm
    cx, cy = W // 4, H // 2
    img[cy - 100: cy + 100, cx - 100: cx + 100] = (190, 190, 200)  # plate, top view
    yaw, u, v = 0.0, 0.0, 0.0
    amp = 0.0
    if result is not None and result.trace is not None and len(result.trace.t):
        yaw = float(result.trace.yaw[-1])
        u, v = float(result.trace.centre_u[-1]) * 1e3, float(result.trace.centre_v[-1]) * 1e3
    if result is not None:
        amp = result.spec.motion.amp_rad
    r = (obj.diameter * 1e3 / 2 if obj is not None else 40.0) * scale
    dx, dy = cx + u * scale, cy - v * scale
    _disc(img, dx, dy, r, (235, 190, 60))
    _line(img, dx, dy, dx + r * math.cos(yaw), dy - r * math.sin(yaw), (160, 60, 20), width=3)
    # side view along the plate axis: the plate tilted by +-A_p
    sx, sy = 3 * W // 4, H // 2 + 20
    half = 100
    for sgn, shade in ((1, (120, 120, 150)), (-1, (170, 170, 200))):
        ex, ey = half * math.cos(amp), sgn * half * math.sin(amp)
        _line(img, sx - ex, sy + ey, sx + ex, sy - ey, shade, width=4)
    _line(img, sx - r / scale * 1.2, sy - 6, sx + r / scale * 1.2, sy - 6, (235, 190, 60), width=4)
    return img


def show(frame: np.ndarray, window=None):
    """Show a frame in a matplotlib window (needs a display); returns the window handle."""
    import matplotlib.pyplot as plt

    if window is None:
        plt.ion()
        fig, ax = plt.subplots()
        ax.axis("off")
        window = (fig, ax.imshow(frame))
    else:
        window[1].set_data(frame)
    window[0].canvas.draw_idle()
    plt.pause(0.001)
    return window


def close_window(window) -> None:
    import matplotlib.pyplot as plt

    plt.close(window[0])
