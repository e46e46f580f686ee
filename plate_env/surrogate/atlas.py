"""The response atlas: omega_B mean, spread and instability probability on a grid over (f_p, A_p, omega_n, alpha).

Built by ``plate-env build atlas`` (:mod:`plate_env.build.atlas`) from repeated probes of a real backend (each
repeat places the disc at a random yaw and offset, as a real experiment would), shipped as package data (``.npz``
with provenance), and interpolated smoothly: tensor-product cubic splines along f_p, log omega_n and alpha (the
spline of scipy's RegularGridInterpolator "cubic"), passing exactly through the grid values; spreads are clipped at 0
and instability probabilities to [0, 1] where the spline overshoots. (Its "pchip" variant would not overshoot but
evaluates orders of magnitude slower: ``experiments/results/bench_interpolation.md``.) Plate amplitudes are not
interpolated: a query must use one of the atlas's amplitudes.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from plate_env.core.filters import bspline_bases, bspline_interval
from plate_env.core.jit import kernels
from plate_env.core.setup import PAPER_SETUP


@dataclass(frozen=True, eq=False)
class Atlas:
    """Tabulated response of one physics backend (arrays shaped (n_f, n_a, n_omega, n_alpha)).

    Attributes:
        f_hz: plate frequencies, Hz. a_p_deg: plate amplitudes, degrees. omega_n: rad/s (log-spaced).
        alpha: friction angles, rad. mean, spread: omega_B mean over stable repeats and its spread (standard
        deviation between repeats combined with their own standard errors), deg/s. p_unstable: share of
        unstable repeats. n_repeats: repeats per grid point. provenance: how it was built.

    Interpolators built from an atlas are kept on the instance (:meth:`cached`), so they live and die with it;
    they are not pickled. Equality is identity (numpy fields have no value equality).
    """

    physics: str
    model: str
    f_hz: np.ndarray
    a_p_deg: np.ndarray
    omega_n: np.ndarray
    alpha: np.ndarray
    mean: np.ndarray
    spread: np.ndarray
    p_unstable: np.ndarray
    n_repeats: int
    provenance: dict = field(default_factory=dict, compare=False)
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def cached(self, key: Hashable, build: Callable[[], Any]) -> Any:
        """``build()`` once per ``key`` for this atlas (interpolators derived from its arrays)."""
        if key not in self._cache:
            self._cache[key] = build()
        return self._cache[key]

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_cache"] = {}
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    def amp_index(self, a_p_deg: float) -> int:
        x = float(a_p_deg)
        for i, a in enumerate(self.a_p_deg.tolist()):  # np.isclose(a, x, atol=1e-6), without its per-call cost
            if abs(a - x) <= 1e-6 + 1e-5 * abs(x):
                return i
        raise ValueError(f"A_p = {a_p_deg!r} deg is not in this atlas; its amplitudes are "
                         f"{[float(a) for a in self.a_p_deg]} deg")

    # -------------------------------------------------------------- domain
    def axes(self) -> dict[str, np.ndarray]:
        """The interpolated axes, SI (a probe must lie within each range): f_p_hz, omega_n (rad/s), alpha (rad)."""
        return {"f_p_hz": self.f_hz, "omega_n": self.omega_n, "alpha": self.alpha}

    def levels(self) -> dict[str, np.ndarray]:
        """Quantities tabulated at discrete values only (a probe must use one of them, sign aside): a_p_deg."""
        return {"a_p_deg": self.a_p_deg}

    def fixed(self) -> dict[str, float]:
        """Quantities the atlas was built at one value of, SI (a probe must match it, sign aside): b_p (m),
        mass (kg), diameter (m), from the provenance's ``b_p_mm``, ``mass_g``, ``diameter_mm``
        (:data:`DEFAULT_BUILD` where it does not record them). A quantity that is an axis or level is not fixed."""
        build = {k: float(self.provenance.get(k, v)) for k, v in DEFAULT_BUILD.items()}
        values = {"b_p": build["b_p_mm"] * 1e-3, "mass": build["mass_g"] * 1e-3,
                  "diameter": build["diameter_mm"] * 1e-3}
        return {k: v for k, v in values.items() if k not in self.axes() and k not in self.levels()}

    def outside(self, **point: float) -> dict[str, str]:
        """Why a probe at ``point`` lies outside what this atlas describes: ``{quantity: reason}``, empty if inside.

        Keywords (SI, as :meth:`axes`, :meth:`levels` and :meth:`fixed` name them): f_p_hz, a_p_deg, omega_n
        (rad/s), alpha (rad), b_p (m), mass (kg), diameter (m); quantities not given are not checked. The atlas is
        sign-normalised, so the signs of a_p_deg and b_p do not matter (a zero does).
        """
        axes, levels, fixed = self.cached(("domain",), self._domain)
        unknown = [k for k in point if k not in axes and k not in levels and k not in fixed]
        if unknown:
            raise ValueError(f"Atlas.outside: unknown quantities {unknown}; known: "
                             f"{sorted({**axes, **levels, **fixed})}")
        where = f"the {self.physics}/{self.model} atlas"
        out: dict[str, str] = {}
        for name, value in point.items():
            x = abs(float(value)) if name in SIGN_NORMALISED else float(value)
            if name in axes:
                lo, hi = axes[name]
                if not (math.isfinite(x) and lo - 1e-9 * abs(lo) <= x <= hi + 1e-9 * abs(hi)):
                    out[name] = f"{_show(name, value)} is outside {where}'s range {_show(name, lo, hi)}"
            elif name in levels:
                if not any(abs(v - x) <= 1e-6 for v in levels[name].tolist()):  # np.isclose(rtol=0, atol=1e-6)
                    held = ", ".join(_show(name, v, unit=False) for v in np.asarray(levels[name]))
                    out[name] = f"{_show(name, value)} is not tabulated in {where} (it holds {held} {_UNITS[name][1]})"
            elif not (math.isfinite(x) and math.isclose(x, fixed[name], rel_tol=1e-6)):
                out[name] = f"{_show(name, value)}: {where} was built at {_show(name, fixed[name])} only"
        return out

    def _domain(self) -> tuple[dict[str, tuple[float, float]], dict[str, np.ndarray], dict[str, float]]:
        """:meth:`outside`'s view of the domain, computed once per atlas: each axis's (min, max), the levels, the
        fixed values."""
        axes = {k: (float(np.min(v)), float(np.max(v))) for k, v in self.axes().items()}
        return axes, self.levels(), self.fixed()

    def _interpolator(self, kind: str, amp: int) -> Callable[[np.ndarray], np.ndarray]:
        """Tensor-product cubic spline of ``kind`` (mean, spread, p_unstable) over (f_p, log omega_n, alpha)."""
        return self.cached(("interp", kind, amp), lambda: _interp(self, kind, amp))

    def predict(self, f_hz, a_p_deg: float, omega_n, alpha) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(mean [deg/s], spread [deg/s], p_unstable) at the given points (broadcast), for one amplitude.

        f_hz, omega_n (rad/s) and alpha (rad) are clipped to the atlas's ranges.
        """
        amp = self.amp_index(a_p_deg)
        f, w, a = np.broadcast_arrays(np.asarray(f_hz, float), np.asarray(omega_n, float), np.asarray(alpha, float))
        pts = np.stack([np.clip(f, self.f_hz[0], self.f_hz[-1]),
                        np.clip(np.log(w), math.log(self.omega_n[0]), math.log(self.omega_n[-1])),
                        np.clip(a, self.alpha[0], self.alpha[-1])], axis=-1)
        flat = pts.reshape(-1, 3)
        mean = self._interpolator("mean", amp)(flat).reshape(f.shape)
        spread = np.maximum(self._interpolator("spread", amp)(flat), 0.0).reshape(f.shape)
        pu = np.clip(self._interpolator("p_unstable", amp)(flat), 0.0, 1.0).reshape(f.shape)
        return mean, spread, pu

    def predict_point(self, f_hz: float, a_p_deg: float, omega_n: float, alpha: float) -> tuple[float, float, float]:
        """:meth:`predict` at one point, as floats (the same values): the three splines share their knots, so the
        B-spline bases are computed once (a probe of the atlas physics needs one point)."""
        amp = self.amp_index(a_p_deg)
        splines = [self._interpolator(kind, amp) for kind in RESPONSE_KINDS]
        if not all(sp.same_knots(splines[0]) for sp in splines[1:]):
            return tuple(float(v) for v in self.predict(f_hz, a_p_deg, omega_n, alpha))
        # np.clip's values (NaN stays NaN), without its per-call cost; the log is numpy's, as predict takes it
        x = [_clip(float(f_hz), float(self.f_hz[0]), float(self.f_hz[-1])),
             _clip(float(np.log(np.asarray(omega_n, float))), math.log(self.omega_n[0]), math.log(self.omega_n[-1])),
             _clip(float(alpha), float(self.alpha[0]), float(self.alpha[-1]))]
        fast = kernels() if x[0] == x[0] and x[1] == x[1] and x[2] == x[2] else None
        if fast is not None and all(sp.c.ndim == 3 for sp in splines):  # the same floats, compiled
            s0 = splines[0]
            mean, spread, pu = fast.spline3_point(*s0.t, *s0.k, *(sp.c for sp in splines), *x)
        else:
            bases = splines[0].bases(x)
            mean, spread, pu = (sp.contract(*bases) for sp in splines)
        return mean, max(spread, 0.0), min(max(pu, 0.0), 1.0)

    def resampled(self, omega_n: np.ndarray) -> Atlas:
        """This atlas on other omega_n nodes (rad/s, increasing, within its range): mean, spread and instability
        share read from its own spline at every (f_p, A_p, alpha) node (exact at the nodes it already has).
        ValueError for nodes outside its omega_n range (no extrapolation)."""
        import dataclasses

        w = np.asarray(omega_n, float)
        lo, hi = float(self.omega_n[0]), float(self.omega_n[-1])
        if w.ndim != 1 or w.size < 2 or np.any(np.diff(w) <= 0) or w[0] < lo * (1 - 1e-9) or w[-1] > hi * (1 + 1e-9):
            raise ValueError(f"resampled: omega_n nodes must increase within {lo:g}-{hi:g} rad/s, got "
                             f"{w.min():g}-{w.max():g} rad/s ({w.size} nodes)")
        f, ww, a = np.meshgrid(self.f_hz, w, self.alpha, indexing="ij")
        out = {k: np.empty((self.f_hz.size, self.a_p_deg.size, w.size, self.alpha.size)) for k in
               ("mean", "spread", "p_unstable")}
        for j, amp in enumerate(self.a_p_deg):
            for k, v in zip(out, self.predict(f, float(amp), ww, a), strict=True):
                out[k][:, j] = v
        prov = dict(self.provenance or {}, resampled=f"{self.omega_n.size} -> {w.size} omega_n nodes by its spline")
        return dataclasses.replace(self, omega_n=w.copy(), provenance=prov, **out)

    # -------------------------------------------------------------- files
    def save(self, path: str | Path) -> None:
        """Write the atlas to ``path`` (``.npz`` added when missing, as numpy adds it) all at once
        (:func:`~plate_env.core.files.write_atomic`: a failure leaves an existing file as it was)."""
        from plate_env.core.files import write_atomic

        path = str(path) if str(path).endswith(".npz") else f"{path}.npz"
        write_atomic(path, lambda tmp: np.savez_compressed(
            tmp, f_hz=self.f_hz, a_p_deg=self.a_p_deg, omega_n=self.omega_n, alpha=self.alpha,
            mean=self.mean.astype(np.float32), spread=self.spread.astype(np.float32),
            p_unstable=self.p_unstable.astype(np.float32),
            meta=np.array(json.dumps({"physics": self.physics, "model": self.model, "n_repeats": self.n_repeats,
                                      "provenance": self.provenance}))), "atlas")

    @classmethod
    def load(cls, path: str | Path) -> Atlas:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            return cls(physics=meta["physics"], model=meta["model"], f_hz=z["f_hz"], a_p_deg=z["a_p_deg"],
                       omega_n=z["omega_n"], alpha=z["alpha"], mean=z["mean"].astype(float),
                       spread=z["spread"].astype(float), p_unstable=z["p_unstable"].astype(float),
                       n_repeats=int(meta["n_repeats"]), provenance=meta["provenance"])


#: Values the shipped atlases were built at, assumed where an atlas's provenance does not record them (edge units).
DEFAULT_BUILD = {"b_p_mm": PAPER_SETUP.b_p_mm, "mass_g": PAPER_SETUP.mass_g, "diameter_mm": PAPER_SETUP.diameter_mm}
#: Quantities the atlas describes by magnitude (omega_B is sign-normalised by sign(A_p B_p)).
SIGN_NORMALISED = ("a_p_deg", "b_p")
#: Edge units of the domain's quantities in messages: (factor from SI, unit, label).
_UNITS = {"f_p_hz": (1.0, "Hz", "f_p"), "a_p_deg": (1.0, "deg", "A_p"), "omega_n": (1 / math.pi, "pi rad/s", "omega_n"),
          "alpha": (180 / math.pi, "deg", "alpha"), "b_p": (1e3, "mm", "B_p"), "mass": (1e3, "g", "mass"),
          "diameter": (1e3, "mm", "diameter")}


def _show(name: str, value: float, hi: float | None = None, unit: bool = True) -> str:
    """``"mass = 39.5 g"`` for a value, ``"13.6-20 g"`` for a range (``hi`` given), in edge units."""
    factor, text, label = _UNITS[name]
    if hi is not None:
        return f"{value * factor:.4g}-{hi * factor:.4g} {text}"
    if not unit:
        return f"{value * factor:.4g}"
    return f"{label} = {value * factor:.4g} {text}"


def _interp(atlas: Atlas, kind: str, amp: int) -> Callable[[np.ndarray], np.ndarray]:
    """The tensor-product cubic spline scipy's ``RegularGridInterpolator(method="cubic", solver=spsolve)`` builds
    (its ``NdBSpline``), evaluated directly at points inside the grid (the same floats, without the interpolator's
    per-call checks). Its coefficients are kept in the disk cache (:mod:`plate_env.core.cache`), keyed by the atlas's
    values and axes: the sparse solve runs once per machine, not once per process."""
    from plate_env.core.cache import cached_arrays, content_key

    values = np.ascontiguousarray(getattr(atlas, kind)[:, amp, :, :], dtype=float)
    axes = (np.asarray(atlas.f_hz, float), np.log(atlas.omega_n), np.asarray(atlas.alpha, float))

    def build() -> dict[str, np.ndarray]:
        from scipy.interpolate import RegularGridInterpolator
        from scipy.sparse.linalg import spsolve

        # a direct solve of the spline system: exact at the nodes (the default iterative solver leaves ~1e-6)
        spl = RegularGridInterpolator(axes, values, method="cubic", solver=spsolve)._spline
        return {"c": spl.c, "k": np.asarray(spl.k), "t0": spl.t[0], "t1": spl.t[1], "t2": spl.t[2]}

    arr = cached_arrays("atlas-spline", content_key("atlas-spline", *axes, values), build)
    return _TensorSpline((arr["t0"], arr["t1"], arr["t2"]), np.array(arr["c"]), tuple(int(k) for k in arr["k"]))


class _TensorSpline:
    """A tensor-product B-spline (knots ``t``, coefficients ``c``, degrees ``k``) evaluated as scipy's ``NdBSpline``
    evaluates it, operation for operation: at a few points in plain Python while scipy.interpolate is not imported
    (an env's first steps do not wait for its import), otherwise through ``NdBSpline`` itself.
    tests/test_atlas.py checks that the two give the same floats."""

    #: Up to this many points are evaluated in Python.
    FEW = 8

    def __init__(self, t: tuple[np.ndarray, ...], c: np.ndarray, k: tuple[int, ...]) -> None:
        self.t, self.c, self.k = t, c, k
        self._t_lists = [list(map(float, td)) for td in t]
        self._c_list = None
        self._scipy = None

    def __call__(self, xi: np.ndarray) -> np.ndarray:
        xi = np.asarray(xi, dtype=float)
        if (xi.ndim == 2 and xi.shape[0] <= self.FEW and xi.shape[1] == len(self.t)
                and "scipy.interpolate" not in sys.modules):  # once scipy is loaded, its faster call serves
            return np.array([self.at(row) for row in xi.tolist()], dtype=float)
        if self._scipy is None:
            from scipy.interpolate import NdBSpline

            self._scipy = NdBSpline(self.t, self.c, self.k)
        return self._scipy(xi)

    def at(self, x: list[float]) -> float:
        """The spline at one point (inside the knots' base interval in every dimension)."""
        return self.contract(*self.bases(x))

    def same_knots(self, other: _TensorSpline) -> bool:
        """Whether ``other`` has this spline's knots and degrees (then :meth:`bases` serve both)."""
        return self.k == other.k and self._t_lists == other._t_lists

    def bases(self, x: list[float]) -> tuple[list[list[float]], list[int]]:
        """The non-zero B-splines at ``x`` per dimension and the first coefficient index they multiply."""
        bases, starts = [], []
        for td, kd, xd in zip(self._t_lists, self.k, x, strict=True):
            ell = bspline_interval(td, kd, xd)
            bases.append(bspline_bases(td, xd, kd, ell))
            starts.append(ell - kd)
        return bases, starts

    def contract(self, bases: list[list[float]], starts: list[int]) -> float:
        """The coefficients summed with the bases' products, term by term in scipy's order."""
        if self._c_list is None:
            self._c_list = self.c.tolist()
        (b0, b1, b2), (s0, s1, s2) = bases, starts
        c = self._c_list
        out = 0.0
        for i0, w0 in enumerate(b0):
            plane = c[s0 + i0]
            for i1, w1 in enumerate(b1):
                line = plane[s1 + i1]
                f01 = 1.0 * w0 * w1
                for i2, w2 in enumerate(b2):
                    out += line[s2 + i2] * (f01 * w2)
        return out


def _clip(x: float, lo: float, hi: float) -> float:
    """``float(np.clip(x, lo, hi))`` for one float (NaN stays NaN)."""
    return min(max(x, lo), hi) if x == x else x


#: The quantities an atlas interpolates, in :meth:`Atlas.predict`'s order.
RESPONSE_KINDS = ("mean", "spread", "p_unstable")
#: Spread (deg/s) given to grid points where no repeat was stable.
FILL_SPREAD = 150.0


def atlas_file(physics: str, model: str) -> str:
    return f"atlas_{physics}_{model}.npz"


def load_atlas(physics: str = "tilelink", model: str = "pointmass") -> Atlas:
    """The shipped atlas of a physics backend."""
    try:
        return load_atlas_file(atlas_file(physics, model))
    except FileNotFoundError:
        raise ValueError(f"no atlas shipped for physics {physics!r} model {model!r} "
                         f"(build one: plate-env build atlas --physics {physics} --model {model})") from None


@lru_cache(maxsize=64)
def load_atlas_file(name: str) -> Atlas:
    """A shipped atlas by file name (package data), loaded once per process (the cache holds every shipped atlas:
    tests/test_manifest.py checks it against the files)."""
    ref = resources.files("plate_env") / "data" / name
    if not ref.is_file():
        raise FileNotFoundError(f"no atlas file {name!r} in plate_env/data")
    with resources.as_file(ref) as p:
        return Atlas.load(p)


def atlas_from_repeats(physics: str, model: str, f_hz, a_p_deg, omega_n, alpha, omega_b: np.ndarray,
                       stderr: np.ndarray, unstable: np.ndarray, provenance: dict) -> Atlas:
    """Reduce repeated probes, arrays shaped (n_f, n_a, n_omega, n_alpha, n_repeats), to an Atlas. Pure.

    Grid points where every repeat was unstable get the mean interpolated from the nearest stable frequencies at
    the same (A_p, omega_n, alpha) and a wide spread (``FILL_SPREAD`` deg/s): a stable probe there may turn at
    quite another rate than the filled mean. A point with a single
    stable repeat has no between-repeat spread of its own and gets at least the median of those that have.
    """
    stable = ~unstable
    n_st = stable.sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n_st > 0, np.sum(np.where(stable, omega_b, 0.0), -1) / np.maximum(n_st, 1), np.nan)
        dev = np.where(stable, (omega_b - mean[..., None]) ** 2, 0.0).sum(-1) / np.maximum(n_st - 1, 1)
        se2 = np.sum(np.where(stable, stderr ** 2, 0.0), -1) / np.maximum(n_st, 1)
    spread = np.sqrt(dev + se2)
    multi = n_st >= 2
    med = float(np.median(spread[multi])) if multi.any() else 1.0
    spread = np.where(n_st == 1, np.maximum(spread, med), spread)
    spread = np.where(n_st == 0, FILL_SPREAD, spread)
    f = np.asarray(f_hz, float)
    for idx in np.ndindex(mean.shape[1:]):
        col = mean[(slice(None), *idx)]
        ok = np.isfinite(col)
        if ok.any() and not ok.all():
            col[~ok] = np.interp(f[~ok], f[ok], col[ok])
        elif not ok.any():
            col[:] = 0.0
    p_un = unstable.mean(-1)
    return Atlas(physics=physics, model=model, f_hz=f, a_p_deg=np.asarray(a_p_deg, float),
                 omega_n=np.asarray(omega_n, float), alpha=np.asarray(alpha, float), mean=mean, spread=spread,
                 p_unstable=p_un, n_repeats=int(omega_b.shape[-1]), provenance=provenance)
