"""Scores of identifications against the truth, with bootstrap confidence intervals over objects. Pure functions.

An identification that gave no estimate counts as an infinite error and as not covered (so a method cannot look
better by refusing hard objects), and the no-estimate rate is reported beside. Errors are relative,
|omega_n_hat - omega_n| / omega_n. Intervals are 95 % percentile-bootstrap intervals over objects (resampled with
replacement, ``n_boot`` times, from a passed-down generator); a 20-object median moves by several points with
placement noise alone, so comparisons of methods or agents should use :func:`paired_difference` on the same
objects and episodes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Stat:
    """A statistic and its 95 % bootstrap interval."""

    value: float
    lo: float
    hi: float

    def to_dict(self) -> dict:
        return {"value": self.value, "ci95": [self.lo, self.hi]}

    def fmt(self, scale: float = 1.0, digits: int = 1, unit: str = "") -> str:
        """``value [lo, hi]`` scaled (e.g. 100 for percent)."""
        return (f"{self.value * scale:.{digits}f}{unit} [{self.lo * scale:.{digits}f}, "
                f"{self.hi * scale:.{digits}f}]")


@dataclass(frozen=True)
class Scores:
    """How well a set of identifications did (each statistic with its bootstrap interval).

    ``median_error``/``p90_error``: relative errors (no estimate = inf); ``coverage68``/``coverage95``: share of
    objects whose truth lies in the 68 %/95 % interval; ``width95``: median 95 % interval width over the truth;
    ``no_estimate``: share without an estimate.
    """

    n: int
    median_error: Stat
    p90_error: Stat
    coverage68: Stat
    coverage95: Stat
    width95: Stat
    no_estimate: Stat

    def to_dict(self) -> dict:
        return {"n": self.n, **{k: getattr(self, k).to_dict() for k in
                                ("median_error", "p90_error", "coverage68", "coverage95", "width95", "no_estimate")}}


def _percentile(x: np.ndarray, q: float, axis: int = -1) -> np.ndarray:
    """numpy's linear percentile, with infinite errors (no estimate) handled: a quantile that lies on an order
    statistic is that statistic, one that lies beyond a finite and an infinite one, or between two infinite ones, is
    inf (numpy gives NaN for some of these: inf - inf, 0 * inf)."""
    with np.errstate(invalid="ignore"):
        out = np.percentile(x, q, axis=axis, method="linear")
    bad = np.isnan(out)
    if np.any(bad) and not np.any(np.isnan(x)):
        n = np.shape(x)[axis]
        on_statistic = (q / 100.0 * (n - 1)) % 1.0 == 0.0
        fix = np.percentile(x, q, axis=axis, method="lower") if on_statistic else np.inf
        out = np.where(bad, fix, out)
    return out


def _in95(e, w: float) -> bool:
    """Whether a 95 % statement holds: the interval of an estimate, or the bound of an answer at the edge of the
    identifiable range (omega_n above / below its 95 % limit)."""
    if e.ok:
        return bool(e.omega_n_ci95[0] <= w <= e.omega_n_ci95[1])
    bound = getattr(e, "bound", None)
    if bound is None:
        return False
    return bool(w > bound[1]) if bound[0] == "above" else bool(w < bound[1])


def per_object(truth: Sequence[float], estimates: Sequence) -> dict[str, np.ndarray]:
    """Per-object arrays: relative error (inf without estimate), in-68 %, in-95 % (an estimate's interval or a
    bound's 95 % statement), 95 % width / truth, ok.

    ``estimates`` are objects with ``ok``, ``omega_n``, ``omega_n_ci68`` and ``omega_n_ci95`` (an
    :class:`~plate_env.identify.estimate.Estimate`)."""
    truth = np.asarray(truth, dtype=float)
    if len(truth) != len(estimates):
        raise ValueError(f"{len(truth)} true values for {len(estimates)} estimates")
    ok = np.array([bool(e.ok) for e in estimates])
    err = np.array([abs(e.omega_n - w) / w if e.ok else math.inf for e, w in zip(estimates, truth, strict=True)])
    in68 = np.array([e.ok and e.omega_n_ci68[0] <= w <= e.omega_n_ci68[1] for e, w in zip(estimates, truth,
                                                                                          strict=True)])
    in95 = np.array([_in95(e, w) for e, w in zip(estimates, truth, strict=True)])
    width = np.array([(e.omega_n_ci95[1] - e.omega_n_ci95[0]) / w if e.ok else math.inf
                      for e, w in zip(estimates, truth, strict=True)])
    return {"error": err, "in68": in68.astype(float), "in95": in95.astype(float), "width95": width,
            "ok": ok.astype(float)}


def _stat(values: np.ndarray, fn, idx: np.ndarray) -> Stat:
    """``fn`` of ``values`` (objects along axis 0) and its 95 % percentile interval over the resamples ``idx``
    (n_boot, n). ``fn`` reduces the object axis of an array (..., n, *rest) to (..., ) -- it is given ``values``
    with a leading resample axis."""
    with np.errstate(invalid="ignore"):
        boot = np.concatenate([fn(values[idx[i:i + 256]]) for i in range(0, len(idx), 256)])  # bounded memory
        return Stat(float(fn(values[None])[0]), float(_percentile(boot, 2.5, 0)), float(_percentile(boot, 97.5, 0)))


def bootstrap(values: Sequence | np.ndarray, fn, rng: np.random.Generator, n_boot: int = 2000) -> Stat:
    """Any statistic of per-object values with its 95 % percentile-bootstrap interval over objects.

    ``values``: (n, ...) with the objects along axis 0 (e.g. (n objects, n budgets) for a whole error curve);
    ``fn(x)`` maps x of shape (b, n, ...) to b numbers (e.g. ``lambda x: np.median(x, axis=1)``)."""
    v = np.asarray(values, dtype=float)
    if v.ndim == 0 or v.shape[0] == 0:
        raise ValueError("bootstrap of no objects")
    return _stat(v, fn, rng.integers(0, v.shape[0], size=(n_boot, v.shape[0])))


def score(truth: Sequence[float], estimates: Sequence, rng: np.random.Generator, n_boot: int = 2000) -> Scores:
    """Scores with 95 % bootstrap intervals over objects."""
    d = per_object(truth, estimates)
    n = len(d["error"])
    if n == 0:
        raise ValueError("no identifications to score")
    idx = rng.integers(0, n, size=(n_boot, n))

    def stat(values: np.ndarray, fn) -> Stat:
        return _stat(values, fn, idx)

    return Scores(n=n,
                  median_error=stat(d["error"], lambda x: np.median(x, axis=-1)),
                  p90_error=stat(d["error"], lambda x: _percentile(x, 90)),
                  coverage68=stat(d["in68"], lambda x: x.mean(-1)),
                  coverage95=stat(d["in95"], lambda x: x.mean(-1)),
                  width95=stat(d["width95"], lambda x: np.median(x, axis=-1)),
                  no_estimate=stat(1.0 - d["ok"], lambda x: x.mean(-1)))


def paired_difference(errors_a: Sequence[float], errors_b: Sequence[float], rng: np.random.Generator,
                      n_boot: int = 2000) -> Stat:
    """Median of the paired differences ``a - b`` of per-object errors on the same objects/episodes, with its
    bootstrap interval (an interval excluding 0 says the two differ on these objects)."""
    a = np.asarray(errors_a, dtype=float)
    b = np.asarray(errors_b, dtype=float)
    if a.shape != b.shape or a.size == 0:
        raise ValueError(f"paired errors need equal, non-empty shapes: {a.shape} vs {b.shape}")
    with np.errstate(invalid="ignore"):
        diff = np.where(np.isinf(a) & np.isinf(b), 0.0, a - b)
    idx = rng.integers(0, diff.size, size=(n_boot, diff.size))
    boot = np.median(diff[idx], axis=1)
    return Stat(float(np.median(diff)), float(_percentile(boot, 2.5, 0)), float(_percentile(boot, 97.5, 0)))


def discrepancies(truth: Sequence[float], estimates: Sequence) -> tuple[np.ndarray, np.ndarray]:
    """``(log(truth / estimate), the estimate's own log-sd)`` per object with an estimate, the inputs of
    :func:`plate_env.identify.inference.fit_sigma_eps`; the log-sd is half the 68 % interval's width in log omega_n.
    ``truth`` may be shorter than ``estimates`` and is then repeated (several data sets of the same objects)."""
    truth = np.asarray(truth, dtype=float)
    if len(estimates) % len(truth):
        raise ValueError(f"{len(estimates)} estimates for {len(truth)} true values")
    truth = np.tile(truth, len(estimates) // len(truth))
    pairs = [(w, e) for w, e in zip(truth, estimates, strict=True) if e.ok]
    eps = np.array([math.log(w / e.omega_n) for w, e in pairs])
    sd = np.array([math.log(e.omega_n_ci68[1] / e.omega_n_ci68[0]) / 2 for _, e in pairs])
    return eps, sd
