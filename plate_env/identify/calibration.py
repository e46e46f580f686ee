"""Eq. (10): omega_n_hat = p1 * f0 + q1, per plate amplitude and physics. Pure functions plus JSON package data.

Units. Inside: ``p1`` in (rad/s)/Hz and ``q1`` in rad/s, so ``omega_n_hat`` is in rad/s. The paper's coefficients
(p1 = 5.30, q1 = -121.62 at 3 deg; 5.65, -64.51 at 12 deg) count omega_n in units of pi rad/s; they are
converted explicitly by :func:`paper_calibration` (multiplied by pi).

Friction (the paper's future work): alongside Eq. (10) the calibration stores a linear model of the friction
angle on the Lorentzian parameters, ``alpha_hat = a0 + a1 * omega_max + a2 * f0`` (degrees at the edge,
radians inside), fitted on the same sweeps and scored by its residual.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from plate_env.core.files import read_json, write_text_atomic

PAPER_COEFFICIENTS_PI = {3.0: (5.30, -121.62), 12.0: (5.65, -64.51)}
DATA_FILE = "calibration.json"


@dataclass(frozen=True)
class Calibration:
    """A fitted Eq. (10) for one physics/model and plate amplitude.

    Attributes:
        physics, model: where the sweeps came from ("paper" for the paper's published coefficients).
        a_p_deg: plate amplitude, degrees.
        p1: (rad/s)/Hz; q1: rad/s; p1_se, q1_se: their standard errors; cov_pq: their covariance.
        r2: coefficient of determination of omega_n on f0; resid_std: residual std of omega_n, rad/s (of a line
            pooled over models: the scatter about each model's own line).
        model_lines: a line pooled over several models: each model's own (p1, q1) (rad/s per Hz, rad/s). The
            offset of a model never seen from the pooled line is Student-t with len - 1 degrees of freedom and the
            scale of the models' offsets at that f0 (:meth:`offset_scale`), as the atlas route's offset between
            models (:func:`plate_env.identify.inference.family_discrepancy`).
        alpha_coef: (a0 [rad], a1 [rad per deg/s], a2 [rad/Hz]) of the friction model; alpha_resid_std: rad.
        provenance: how it was made (objects, amplitudes, dt, window, version).
    """

    physics: str
    model: str
    a_p_deg: float
    p1: float
    q1: float
    p1_se: float = 0.0
    q1_se: float = 0.0
    cov_pq: float = 0.0
    r2: float = float("nan")
    resid_std: float = 0.0
    n: int = 0
    alpha_coef: tuple[float, float, float] | None = None
    alpha_resid_std: float = 0.0
    provenance: dict = field(default_factory=dict, compare=False)
    model_lines: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if len(self.model_lines) == 1:
            raise ValueError("model_lines: a line pooled over models needs at least two models' lines (none: one "
                             "model)")

    @property
    def offset_nu(self) -> float:
        """Degrees of freedom of the offset between models (inf: no offset, a single model's line)."""
        return float(len(self.model_lines) - 1) if self.model_lines else math.inf

    def offset_scale(self, f0_hz: float) -> float:
        """Scale (rad/s) of the offset of a model never seen from the pooled line at ``f0_hz`` (0 for a single
        model's line): the predictive scale of a new draw from the K models' lines there, ``s sqrt(1 + 1/K)`` with
        ``s^2`` their squared spread about the pooled line over K - 1."""
        if not self.model_lines:
            return 0.0
        k = len(self.model_lines)
        w = self.omega_n(f0_hz)
        s2 = float(np.sum([(p * f0_hz + q - w) ** 2 for p, q in self.model_lines])) / (k - 1)
        return math.sqrt(s2 * (1.0 + 1.0 / k))

    def omega_n(self, f0_hz: float) -> float:
        """omega_n_hat (rad/s) from the Lorentzian f0 (Hz)."""
        return self.p1 * f0_hz + self.q1

    def omega_n_stderr(self, f0_hz: float, f0_se_hz: float) -> float:
        """Standard error of omega_n_hat (rad/s): f0's error, the coefficients' errors, the scatter about the line."""
        var = (self.p1 * f0_se_hz) ** 2 + (f0_hz * self.p1_se) ** 2 + self.q1_se ** 2 + 2 * f0_hz * self.cov_pq
        return math.sqrt(max(var, 0.0) + self.resid_std ** 2)

    def alpha(self, omega_max_deg_s: float, f0_hz: float) -> float | None:
        """alpha_hat (rad) from the Lorentzian omega_max and f0, or None if this calibration has no friction model."""
        if self.alpha_coef is None:
            return None
        a0, a1, a2 = self.alpha_coef
        return a0 + a1 * omega_max_deg_s + a2 * f0_hz

    @property
    def p1_pi(self) -> float:
        """p1 in the paper's units ((pi rad/s)/Hz)."""
        return self.p1 / math.pi

    @property
    def q1_pi(self) -> float:
        return self.q1 / math.pi

    def to_json(self) -> dict:
        d = asdict(self)
        d["alpha_coef"] = list(self.alpha_coef) if self.alpha_coef is not None else None
        d["model_lines"] = [list(line) for line in self.model_lines]
        if not self.model_lines:
            del d["model_lines"]
        return d

    @classmethod
    def from_json(cls, d: dict) -> Calibration:
        d = dict(d)
        if d.get("alpha_coef") is not None:
            d["alpha_coef"] = tuple(float(x) for x in d["alpha_coef"])
        d["model_lines"] = tuple((float(p), float(q)) for p, q in d.get("model_lines", ()))
        return cls(**d)


def paper_calibration(a_p_deg: float) -> Calibration:
    """The paper's Eq. (10) coefficients (Section 6.1), converted from pi rad/s to rad/s."""
    try:
        p1, q1 = PAPER_COEFFICIENTS_PI[float(a_p_deg)]
    except KeyError:
        raise ValueError(f"the paper gives Eq. (10) only for A_p in {sorted(PAPER_COEFFICIENTS_PI)} deg, "
                         f"not {a_p_deg!r}") from None
    return Calibration(physics="paper", model="paper", a_p_deg=float(a_p_deg), p1=p1 * math.pi, q1=q1 * math.pi,
                       provenance={"source": "paper Section 6.1, omega_n in units of pi rad/s"})


def linear_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float, float, float, float]:
    """Least squares y = p x + q: (p, q, p_se, q_se, cov_pq, r2, resid_std)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    n = len(x)
    if n < 3 or np.ptp(x) == 0:
        raise ValueError(f"a calibration line needs >= 3 points with different f0, got {n}")
    a = np.column_stack([x, np.ones(n)])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    res = y - a @ coef
    s2 = float(res @ res) / (n - 2)
    cov = s2 * np.linalg.inv(a.T @ a)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(res @ res) / ss_tot if ss_tot > 0 else float("nan")
    return (float(coef[0]), float(coef[1]), math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1]), float(cov[0, 1]), r2,
            math.sqrt(s2))


def fit_calibration(f0_hz, omega_n_rad_s, physics: str, model: str, a_p_deg: float, omega_max_deg_s=None,
                    alpha_rad=None, provenance: dict | None = None, groups=None) -> Calibration:
    """Fit Eq. (10) (omega_n on f0, as the paper regresses it) and, given omega_max and the true alphas, the
    friction model. ``groups`` (one label per point): the points come from several models; the lines of the
    models with at least 3 points are kept (``model_lines``, when there are two or more) and the residual scatter is
    the one about those models' own lines. Pure."""
    p, q, pse, qse, cpq, r2, rs = linear_fit(f0_hz, omega_n_rad_s)
    lines: tuple[tuple[float, float], ...] = ()
    if groups is not None:
        g = np.asarray(groups)
        x, y = np.asarray(f0_hz, float), np.asarray(omega_n_rad_s, float)
        # models with a line of their own (>= 3 points at different f0); the others count in the pooled line only
        lined = [k for k in sorted(set(groups)) if (g == k).sum() >= 3 and np.ptp(x[g == k]) > 0]
        if len(lined) >= 2:
            fits = [linear_fit(x[g == k], y[g == k]) for k in lined]
            lines = tuple((f[0], f[1]) for f in fits)
            resid = np.concatenate([y[g == k] - (f[0] * x[g == k] + f[1]) for k, f in zip(lined, fits, strict=True)])
            rs = math.sqrt(float(resid @ resid) / max(len(resid) - 2 * len(fits), 1))
    alpha_coef, alpha_rs = None, 0.0
    if omega_max_deg_s is not None and alpha_rad is not None:
        x = np.column_stack([np.ones(len(f0_hz)), np.asarray(omega_max_deg_s, float), np.asarray(f0_hz, float)])
        y = np.asarray(alpha_rad, float)
        if len(y) > 3:
            c, *_ = np.linalg.lstsq(x, y, rcond=None)
            alpha_coef = (float(c[0]), float(c[1]), float(c[2]))
            alpha_rs = float(np.sqrt(np.sum((y - x @ c) ** 2) / (len(y) - 3)))
    return Calibration(physics=physics, model=model, a_p_deg=float(a_p_deg), p1=p, q1=q, p1_se=pse, q1_se=qse,
                       cov_pq=cpq, r2=r2, resid_std=rs, n=len(f0_hz), alpha_coef=alpha_coef,
                       alpha_resid_std=alpha_rs, provenance=dict(provenance or {}), model_lines=lines)


def _key(physics: str, model: str, a_p_deg: float) -> str:
    return f"{physics}/{model}/{float(a_p_deg):g}"


def save_calibrations(cals: list[Calibration], path: str | Path) -> None:
    """Write calibrations to JSON (keyed physics/model/amplitude)."""
    data = {_key(c.physics, c.model, c.a_p_deg): c.to_json() for c in cals}
    write_text_atomic(path, json.dumps(data, indent=1, sort_keys=True) + "\n", "calibration")


def load_calibrations(path: str | Path | None = None) -> dict[str, Calibration]:
    """Read calibrations (the package's own file by default)."""
    if path is None:
        ref = resources.files("plate_env") / "data" / DATA_FILE
        if not ref.is_file():
            return {}
        text = ref.read_text()
    else:
        return {k: Calibration.from_json(v) for k, v in read_json(path, "Eq. (10) calibrations").items()}
    return {k: Calibration.from_json(v) for k, v in json.loads(text).items()}


def get_calibration(physics: str, model: str, a_p_deg: float, path: str | Path | None = None) -> Calibration:
    """The stored calibration for a physics/model at a plate amplitude; ``physics="paper"`` gives the paper's."""
    if physics == "paper":
        return paper_calibration(a_p_deg)
    cals = load_calibrations(path)
    key = _key(physics, model, a_p_deg)
    if key not in cals:
        raise ValueError(f"no calibration for {key}; available: {sorted(cals) or 'none'} (the package's lines are "
                         "rebuilt by `plate-env build calibration eq10`; a line of another physics or model is "
                         "fitted by experiments/calibrate.py in a checkout)")
    return cals[key]
