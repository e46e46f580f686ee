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


class PyBulletRenderer:
    """Draws the plate and the disc with PyBullet's TinyRenderer (software, no GUI) in its own DIRECT client.

    The client holds only visual bodies (a plate box and a disc cylinder) posed from the last probe: the plate
    tilted by its amplitude, the disc at its last yaw and centre. It is created on the first render and
    disconnected by :meth:`close`.
    """

    def __init__(self, width: int = W, height: int = H) -> None:
        import pybullet as p

        self.p = p
        self.width, self.height = width, height
        self.cid = p.connect(p.DIRECT)
        plate_vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[0.06, 0.06, 0.002], rgbaColor=[0.6, 0.6, 0.7, 1],
                                        physicsClientId=self.cid)
        disc_vis = p.createVisualShape(p.GEOM_CYLINDER, radius=0.04, length=0.002, rgbaColor=[0.95, 0.75, 0.25, 1],
                                       physicsClientId=self.cid)
        mark_vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[0.02, 0.002, 0.0012], rgbaColor=[0.6, 0.25, 0.1, 1],
                                       physicsClientId=self.cid)
        self.plate = p.createMultiBody(baseVisualShapeIndex=plate_vis, physicsClientId=self.cid)
        self.disc = p.createMultiBody(baseVisualShapeIndex=disc_vis, physicsClientId=self.cid)
        self.mark = p.createMultiBody(baseVisualShapeIndex=mark_vis, physicsClientId=self.cid)

    def draw(self, result, obj) -> np.ndarray:
        p = self.p
        yaw, u, v, tilt = 0.0, 0.0, 0.0, 0.0
        if result is not None:
            tilt = result.spec.motion.amp_rad
            if result.trace is not None and len(result.trace.t):
                yaw = float(result.trace.yaw[-1])
                u, v = float(result.trace.centre_u[-1]), float(result.trace.centre_v[-1])
        plate_q = p.getQuaternionFromEuler([tilt, 0, 0])
        p.resetBasePositionAndOrientation(self.plate, [0, 0, -0.002], plate_q, physicsClientId=self.cid)
        rot = np.array(p.getMatrixFromQuaternion(plate_q)).reshape(3, 3)
        centre = rot @ np.array([u, v, 0.001])
        disc_q = p.multiplyTransforms([0, 0, 0], plate_q, [0, 0, 0], p.getQuaternionFromEuler([0, 0, yaw]))[1]
        p.resetBasePositionAndOrientation(self.disc, centre.tolist(), disc_q, physicsClientId=self.cid)
        mark = centre + rot @ np.array([0.02 * math.cos(yaw), 0.02 * math.sin(yaw), 0.001])
        p.resetBasePositionAndOrientation(self.mark, mark.tolist(), disc_q, physicsClientId=self.cid)
        view = p.computeViewMatrix([0.0, -0.16, 0.14], [0, 0, 0], [0, 0, 1])
        proj = p.computeProjectionMatrixFOV(50, self.width / self.height, 0.01, 1.0)
        img = p.getCameraImage(self.width, self.height, view, proj, renderer=p.ER_TINY_RENDERER,
                               physicsClientId=self.cid)[2]
        return np.asarray(img, dtype=np.uint8).reshape(self.height, self.width, 4)[..., :3].copy()

    def close(self) -> None:
        if self.cid is not None:
            self.p.disconnect(self.cid)
            self.cid = None
