"""omega_n of the PyBullet sheet, measured by a virtual test, and the stiffness -> omega_n calibration.

The virtual test ("hang and release", free-free saddle ring-down):

1. Build the sheet alone (no plate) in a weak gravity ``g_hang = min(9.81, 0.03 k) m/s^2`` (k in N/m) and hold
   the rim nodes within 0.2 rad of azimuth 0 and pi (both layers) with world anchors for 0.4 s: the sheet sags
   into a shape dominated by the two-nodal-diameter "saddle" bending mode, a few tenths of a millimetre deep
   (the weak gravity keeps the test linear; at 9.81 m/s^2 soft sheets took a permanent set and did not ring).
2. Remove the anchors and switch gravity off: the free sheet rings in free-free bending.
3. Project the node heights (minus their mean) on the saddle pattern ``(r/R)^2 cos 2 phi`` every 2 steps and
   take the frequency of the largest peak of that coordinate's spectrum (minus its mean, Hann window) over
   ``T = max(1 s, 5/f_guess)``.

That frequency times 2 pi is the sheet's omega_n: the lowest free bending mode of a free disc is the saddle
mode, as in the tile-link model's modal analysis. ``resetMeshData`` is NOT used to impose a deflection: with it
the sheet stayed deflected and did not ring (it appears to reset more than positions).

Calibration: ``k_elastic`` (``springElasticStiffness``, N/m, all tetrahedron edges) is the stiffness knob; the
measured omega_n follows ``sqrt(k)`` closely (a linear spring network with fixed masses), so the table holds
measured (k, omega_n) pairs and is interpolated linearly in (log k, log omega_n).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import asdict
from functools import lru_cache
from importlib import resources

import numpy as np

from plate_env.core.objects import ObjectSpec
from plate_env.physics.pybullet_sheet.scene import Client, SheetConfig, SheetScene

#: Stiffness grid (N/m) of the stored calibration table.
K_GRID = (0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 400.0)
TABLE_FILE = "pybullet_calibration.json"


def ringdown_omega_n(client: Client, obj: ObjectSpec, k_elastic: float, config: SheetConfig,
                     hang_s: float = 0.4) -> float:
    """The sheet's first free bending angular frequency (rad/s) by the hang-and-release test; NaN if it fails."""
    g_hang = min(9.81, 0.03 * k_elastic)
    scene = SheetScene(client, obj, k_elastic, config, gravity=g_hang, with_plate=False)
    p, cid = client.p, client.cid
    x0 = scene.mesh.nodes
    r = np.hypot(x0[:, 0], x0[:, 1])
    phi = np.arctan2(x0[:, 1], x0[:, 0])
    rim = r > 0.95 * r.max()
    hold = np.where(rim & ((np.abs(phi) < 0.2) | (np.abs(np.abs(phi) - math.pi) < 0.2)))[0]
    anchors = [p.createSoftBodyAnchor(scene.body, int(i), -1, -1, physicsClientId=cid) for i in hold]
    dt = config.dt
    for _ in range(int(round(hang_s / dt))):
        scene.step()
    for a in anchors:
        p.removeConstraint(a, physicsClientId=cid)
    p.setGravity(0.0, 0.0, 0.0, physicsClientId=cid)
    f_guess = 1.5 * math.sqrt(max(k_elastic, 1e-6))  # Hz, rough sqrt(k) law of the default mesh
    dur = max(1.0, 5.0 / f_guess)
    w = (r / r.max()) ** 2 * np.cos(2.0 * phi)
    every = 2
    q = []
    for i in range(int(round(dur / dt))):
        scene.step()
        if i % every == 0:
            z = scene.positions()[:, 2]
            q.append(float(((z - z.mean()) * w).sum() / (w * w).sum()))
    q_arr = np.asarray(q)
    if not np.isfinite(q_arr).all():
        return math.nan
    return 2.0 * math.pi * spectral_peak_frequency(q_arr - q_arr.mean(), every * dt, 0.4 * f_guess, 2.5 * f_guess)


def spectral_peak_frequency(y: np.ndarray, dt: float, f_lo: float, f_hi: float) -> float:
    """Frequency (Hz) of the largest peak in ``[f_lo, f_hi]`` of the Hann-windowed, 16x zero-padded spectrum of ``y``.

    The band (0.4-2.5x a rough sqrt(k) guess) keeps the slow drift of the freely floating sheet (its rigid spin
    modulates the fixed saddle pattern) and higher modes out of the peak search.
    """
    n = len(y)
    spec = np.abs(np.fft.rfft(y * np.hanning(n), 16 * n))
    freqs = np.fft.rfftfreq(16 * n, dt)
    spec[(freqs < f_lo) | (freqs > f_hi)] = 0.0
    return float(freqs[int(np.argmax(spec))])


def _config_key(config: SheetConfig) -> dict:
    d = asdict(config)
    return {k: d[k] for k in ("n_layer", "thickness", "dt", "margin", "damping_time", "bending_ratio")}


def measure_table(config: SheetConfig, obj: ObjectSpec | None = None,
                  k_grid: tuple[float, ...] = K_GRID) -> dict:
    """Measure omega_n (rad/s) at each stiffness of ``k_grid`` for ``obj``'s mass and diameter."""
    obj = obj or ObjectSpec()
    client = Client()
    try:
        omegas = [ringdown_omega_n(client, obj, k, config) for k in k_grid]
    finally:
        client.close()
    return {"config": _config_key(config), "mass": obj.mass, "diameter": obj.diameter,
            "k_elastic": list(k_grid), "omega_n": omegas}


def stored_table() -> dict | None:
    """The calibration table shipped in ``plate_env/data`` (None if absent)."""
    try:
        text = resources.files("plate_env").joinpath("data", TABLE_FILE).read_text()
    except (FileNotFoundError, ModuleNotFoundError):
        return None
    return json.loads(text)


@lru_cache(maxsize=32)
def _table_for(config: SheetConfig, mass: float, diameter: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    tab = stored_table()
    if tab is None:
        tab = measure_table(config, ObjectSpec(mass=mass, diameter=diameter))
    # a mass-spring network keeps its mode shapes when all k scale with the mass: k ~ mass at fixed omega_n
    scale = mass / tab["mass"]
    pairs = [(k * scale, w) for k, w in zip(tab["k_elastic"], tab["omega_n"], strict=True) if math.isfinite(w)]
    return tuple(k for k, _ in pairs), tuple(w for _, w in pairs)


def k_for_omega_n(obj: ObjectSpec, config: SheetConfig) -> float:
    """``springElasticStiffness`` (N/m) that gives ``obj.omega_n``: log-log interpolation of the table.

    The stored table was measured for the default config and the paper's cheese (13.6 g, 80 mm); for another
    mass, diameter or config it is only a starting guess that :func:`calibrated_k` corrects by measurement.
    Outside the table the ``sqrt(k)`` law extrapolates from the nearest end.
    """
    ks, ws = _table_for(config, obj.mass, obj.diameter)
    lk, lw = np.log(ks), np.log(ws)
    target = math.log(obj.omega_n)
    if target <= lw[0]:
        return float(math.exp(lk[0] + 2.0 * (target - lw[0])))
    if target >= lw[-1]:
        return float(math.exp(lk[-1] + 2.0 * (target - lw[-1])))
    return float(math.exp(np.interp(target, lw, lk)))


#: The friction angle every calibration is keyed and run with (rad): the ring-down hangs and releases the sheet with
#: no plate and no self-collision, so nothing touches it and its friction (``obj.alpha``) cannot change the result.
RINGDOWN_ALPHA = math.radians(45.0)


def calibrated_k(obj: ObjectSpec, config: SheetConfig, tol: float = 0.02, max_iter: int = 8) -> tuple[float, float]:
    """``(k_elastic N/m, measured omega_n rad/s)`` for ``obj.omega_n``: table start, then ring-down refinement.

    The disc's friction angle is no input (:data:`RINGDOWN_ALPHA`): objects that differ in alpha only share one
    calibration (an env's random objects, an atlas's alpha axis), instead of one ring-down series each.

    The ring-down estimate wiggles by up to ~10 % around the sqrt(k) law between table points, so the table
    value is checked by a ring-down at that k and corrected with ``k *= (target / measured)^2`` until the
    measured omega_n is within ``tol`` (at most ``max_iter`` ring-downs, ~0.5-2 s each). Once per object and
    process, and kept in the disk cache (:mod:`plate_env.core.cache`) keyed by the object, the config, the tolerances,
    the pybullet version and this package's PyBullet source: a new process reads it instead of running the
    ring-downs again. Returns the best pair seen.
    """
    return _calibrated_k(dataclasses.replace(obj, alpha=RINGDOWN_ALPHA), config, tol, max_iter)


@lru_cache(maxsize=256)
def _calibrated_k(obj: ObjectSpec, config: SheetConfig, tol: float, max_iter: int) -> tuple[float, float]:
    import pybullet

    from plate_env.core.cache import cached_arrays, content_key

    key = content_key("pybullet-k", repr(obj), repr(config), tol, max_iter, _source_digest(),
                      getattr(pybullet, "getAPIVersion", lambda: "?")())
    arr = cached_arrays("pybullet-k", key, lambda: {"k_w": np.array(_ringdown_k(obj, config, tol, max_iter))},
                        note=f"calibrating the PyBullet sheet's stiffness to omega_n = {obj.omega_n:.4g} rad/s by "
                             "ring-downs")
    k, w = (float(x) for x in arr["k_w"])
    return k, w


@lru_cache(maxsize=1)
def _source_digest() -> str:
    """SHA-256 of this package's PyBullet sheet source files (a change to them invalidates cached calibrations)."""
    import hashlib
    from pathlib import Path

    h = hashlib.sha256()
    for p in sorted(Path(__file__).parent.glob("*.py")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def _ringdown_k(obj: ObjectSpec, config: SheetConfig, tol: float, max_iter: int) -> tuple[float, float]:
    """:func:`calibrated_k` by ring-downs, without the caches."""
    k = k_for_omega_n(obj, config)
    best = (k, math.nan)
    lo, hi = 0.0, math.inf  # bracket: omega_n(lo) < target < omega_n(hi)
    client = Client()
    try:
        for _ in range(max_iter):
            w = ringdown_omega_n(client, obj, k, config)
            if not math.isfinite(w):
                break
            if not math.isfinite(best[1]) or abs(w / obj.omega_n - 1) < abs(best[1] / obj.omega_n - 1):
                best = (k, w)
            if abs(w / obj.omega_n - 1) < tol:
                break
            if w < obj.omega_n:
                lo = max(lo, k)
            else:
                hi = min(hi, k)
            k *= (obj.omega_n / w) ** 2
            if not lo < k < hi and 0.0 < lo and math.isfinite(hi):
                k = math.sqrt(lo * hi)  # the estimate is not monotone there: bisect the bracket in log k
    finally:
        client.close()
    return best


def table_text(table: dict) -> str:
    """The text of a :func:`measure_table` table as shipped in ``plate_env/data/pybullet_calibration.json``."""
    return json.dumps(table, indent=1) + "\n"


if __name__ == "__main__":
    raise SystemExit("the table is rebuilt by `plate-env build pybullet-table --out pybullet_calibration.json` "
                     "(plate_env.build.pybullet_table)")
