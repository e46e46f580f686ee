"""The ``info`` of :class:`~plate_env.env.rotation.PlateRotationEnv`, declared in one place (issues 38 and 41).

:data:`FIELDS` lists every key (dotted for nested dicts), its dtype, unit, the steps on which it holds a value and
its meaning. Every key is in every ``info`` (``reset`` and every ``step``), with the same dtype, whatever happens:
batching libraries (Gymnasium's vector envs, tianshou's ``Batch``, Stable-Baselines3's ``Monitor(info_keywords=)``)
need keys that do not come and go. A key without a value holds its field's ``empty`` value and a bool flag says
whether there is a value (``estimate.ok``, ``estimate.check.ok``, ``last_probe.ok``, ``truth_revealed``): ``""``
for strings, 0 for numbers (the fill value Gymnasium's vector envs use for an absent info entry), and ``inf`` for
``relative_error`` (no estimate is no bounded error; a 0 there would read as a perfect answer in a log). No value is
ever NaN: tianshou's trainers refuse a replay buffer holding a NaN anywhere, info included ("Encountered NaNs in
buffer", ``experiments/tianshou_ppo.py``), and a NaN never equals itself, so Gymnasium's ``check_env`` would find
two runs of the same seeds unequal.

The hidden object (``*_true_*`` and ``last_probe``'s ``omega_n_rad_s``, ``alpha_deg``, ``mass_g``) is empty (0) until
the step that terminates the episode (the env's ``reveal_truth=True`` shows it on every step, for diagnostics only):
an agent that reads the info (tianshou passes it to the policy) learns nothing it could not measure.

:func:`build` makes an info from the values the env has; :func:`problems` checks one against :data:`FIELDS`;
:func:`markdown` renders the table that the env's docstring and docs/env.md show.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np

if TYPE_CHECKING:
    from plate_env.identify.estimate import Estimate

#: When a field holds a value (the words :func:`markdown` shows).
EVERY, PROBED, FINAL, ESTIMATE, CHECKED = ("every step", "after the first probe", "terminating step",
                                           "terminating step with an estimate", "terminating step, method atlas")
HIDDEN = "terminating step (hidden before it)"


@dataclass(frozen=True)
class Field:
    """One info key: ``key`` (dotted for nested dicts), ``dtype`` (``float64``, ``int64``, ``bool``, ``str``),
    ``unit`` (``-`` for none), ``when`` it holds a value (it is present on every step), ``meaning``, and the
    ``empty`` value it holds otherwise."""

    key: str
    dtype: str
    unit: str
    when: str
    meaning: str
    #: The value the key holds when it has none (see the module docstring); None: the dtype's (0, False, "").
    empty: float | None = None


_F, _I, _B, _S = "float64", "int64", "bool", "str"
#: The type of an info value (a leaf of the nested dict): one per dtype.
InfoValue: TypeAlias = np.float64 | np.int64 | np.bool_ | str

#: Every info key. The order is the info's order.
FIELDS: tuple[Field, ...] = (
    Field("omega_n_true_rad_s", _F, "rad/s", HIDDEN, "the hidden object's omega_n"),
    Field("alpha_true_rad", _F, "rad", HIDDEN, "the hidden object's friction angle alpha"),
    Field("mass_true_kg", _F, "kg", HIDDEN, "the hidden object's mass"),
    Field("truth_revealed", _B, "-", EVERY, "the three fields above and last_probe's hidden ones hold the truth"),
    Field("probes", _I, "-", EVERY, "probes run so far"),
    Field("sim_s", _F, "s", EVERY, "simulated seconds the probes took so far"),
    Field("wall_s", _F, "s", FINAL, "the episode's wall-clock seconds (the one non-deterministic number)"),
    Field("relative_error", _F, "-", ESTIMATE, "abs(omega_n_hat - omega_n) / omega_n (uncapped; the reward caps it); "
          "inf without an estimate", empty=math.inf),
    Field("estimate.ok", _B, "-", EVERY, "an estimate was made (False before the terminating step)"),
    Field("estimate.method", _S, "-", FINAL, "the estimate's method (atlas or lorentz)"),
    Field("estimate.reason", _S, "-", FINAL, "why there is no estimate (empty with one)"),
    Field("estimate.forward", _S, "-", FINAL, "the forward model the atlas method used"),
    Field("estimate.omega_n_rad_s", _F, "rad/s", FINAL, "omega_n_hat"),
    Field("estimate.omega_n_stderr_rad_s", _F, "rad/s", FINAL, "half the 68 % interval"),
    Field("estimate.omega_n_pi", _F, "pi rad/s", FINAL, "omega_n_hat / pi"),
    Field("estimate.omega_n_ci68_lo_rad_s", _F, "rad/s", FINAL, "68 % interval, lower end"),
    Field("estimate.omega_n_ci68_hi_rad_s", _F, "rad/s", FINAL, "68 % interval, upper end"),
    Field("estimate.omega_n_ci95_lo_rad_s", _F, "rad/s", FINAL, "95 % interval, lower end"),
    Field("estimate.omega_n_ci95_hi_rad_s", _F, "rad/s", FINAL, "95 % interval, upper end"),
    Field("estimate.alpha_deg", _F, "deg", FINAL, "alpha_hat, when the method gives one"),
    Field("estimate.alpha_stderr_deg", _F, "deg", FINAL, "its standard error"),
    Field("estimate.n_probes", _I, "-", FINAL, "probes the estimate read (0 before)"),
    Field("estimate.n_unstable", _I, "-", FINAL, "of which unstable (0 before)"),
    Field("estimate.bound.side", _S, "-", FINAL, "above/below when the answer is at the edge of the identifiable "
          "range (no estimate then), else empty"),
    Field("estimate.bound.omega_n_rad_s", _F, "rad/s", FINAL, "omega_n is above/below this at 95 %"),
    Field("estimate.check.ok", _B, "-", EVERY, "a predictive check of the probes was made"),
    Field("estimate.check.passed", _B, "-", CHECKED, "p_value >= p_min (a failed check is no estimate)"),
    Field("estimate.check.statistic", _F, "-", CHECKED, "the probes' surprise at the best fit"),
    Field("estimate.check.p_value", _F, "-", CHECKED, "share of replicated sweeps at least as surprising"),
    Field("estimate.check.p_min", _F, "-", CHECKED, "the check's level"),
    Field("estimate.check.n_probes", _I, "-", CHECKED, "probes checked (0 without a check)"),
    Field("estimate.check.member", _S, "-", CHECKED, "the forward-model member checked"),
    Field("estimate.check.worst.f_p_hz", _F, "Hz", CHECKED, "the probe explained worst: its f_p"),
    Field("estimate.check.worst.a_p_deg", _F, "deg", CHECKED, "its A_p"),
    Field("estimate.check.worst.z", _F, "-", CHECKED, "its residual, in model scales"),
    Field("last_probe.ok", _B, "-", EVERY, "a probe has run (the fields below describe the latest one)"),
    Field("last_probe.f_p_hz", _F, "Hz", PROBED, "plate frequency"),
    Field("last_probe.a_p_deg", _F, "deg", PROBED, "plate amplitude"),
    Field("last_probe.b_p_mm", _F, "mm", PROBED, "plate translation amplitude"),
    Field("last_probe.omega_b_deg_s", _F, "deg/s", PROBED, "omega_B as the camera measured it, the value of the "
          "observation and the estimate; 0 for an unstable probe (it has no rotation rate)"),
    Field("last_probe.stderr_deg_s", _F, "deg/s", PROBED, "its standard error (0 for an unstable probe)"),
    Field("last_probe.unstable", _B, "-", PROBED, "the disc left the plate or slipped (False before a probe)"),
    Field("last_probe.reason", _S, "-", PROBED, "why it is unstable (empty for a stable probe)"),
    Field("last_probe.sim_s", _F, "s", PROBED, "simulated seconds it took"),
    Field("last_probe.periods_measured", _I, "-", PROBED, "plate periods in its window (0 before a probe)"),
    Field("last_probe.omega_n_rad_s", _F, "rad/s", HIDDEN, "the hidden object's omega_n"),
    Field("last_probe.alpha_deg", _F, "deg", HIDDEN, "the hidden object's alpha"),
    Field("last_probe.mass_g", _F, "g", HIDDEN, "the hidden object's mass"),
)

#: The keys whose value is the hidden object (empty until the terminating step unless ``reveal_truth``).
HIDDEN_KEYS = tuple(f.key for f in FIELDS if f.when == HIDDEN)
_PATHS = tuple((f.key.split("."), f.dtype) for f in FIELDS)
_KEYS = frozenset(f.key for f in FIELDS)
_CAST: dict[str, Callable[[Any], InfoValue]] = {_F: np.float64, _I: np.int64, _B: np.bool_, _S: str}
_EMPTY: dict[str, InfoValue] = {_F: np.float64(0.0), _I: np.int64(0), _B: np.bool_(False), _S: ""}


def empty_value(f: Field) -> InfoValue:
    """The value ``f`` holds without a value: its ``empty``, else its dtype's (0.0, 0, False, "")."""
    return _EMPTY[f.dtype] if f.empty is None else _CAST[f.dtype](f.empty)


def _value(v: Any, f: Field) -> InfoValue:
    """``v`` cast to ``f``'s dtype; None, or a NaN (a number that is no value), gives ``f``'s empty value."""
    if v is None:
        return empty_value(f)
    out = _CAST[f.dtype](v)
    return empty_value(f) if isinstance(out, np.float64) and math.isnan(out) else out  # float64: dtype _F


def build(values: dict[str, Any]) -> dict[str, Any]:
    """The info of :data:`FIELDS` from ``values`` (dotted key -> value; a key left out or None holds nothing),
    each value cast to its field's dtype. A key that is not a field is refused (KeyError): the schema is here."""
    unknown = values.keys() - _KEYS
    if unknown:
        raise KeyError(f"info keys {sorted(unknown)} are not declared in plate_env.env.info.FIELDS")
    info: dict[str, Any] = {}
    for (path, _), f in zip(_PATHS, FIELDS, strict=True):
        d = info
        for p in path[:-1]:
            d = d.setdefault(p, {})
        d[path[-1]] = _value(values.get(f.key), f)
    return info


def flatten(info: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """``info`` as dotted key -> value."""
    out: dict[str, Any] = {}
    for k, v in info.items():
        if isinstance(v, dict):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


_TYPES = {_F: np.float64, _I: np.int64, _B: np.bool_, _S: str}


def problems(info: dict[str, Any]) -> list[str]:
    """What is wrong with ``info`` against :data:`FIELDS` (missing or extra keys, a value of another type); empty
    when it follows the schema."""
    flat = flatten(info)
    out = [f"missing {k}" for k in sorted(_KEYS - flat.keys())]
    out += [f"undeclared {k}" for k in sorted(flat.keys() - _KEYS)]
    out += [f"{f.key} is {type(flat[f.key]).__name__}, not {f.dtype}" for f in FIELDS
            if f.key in flat and not isinstance(flat[f.key], _TYPES[f.dtype])]
    return out


def _shown(v: InfoValue, code: str) -> str:
    return f'{code}""{code}' if isinstance(v, str) else str(v).lower() if isinstance(v, np.bool_) else f"{v:g}"


def markdown(code: str = "`") -> str:
    """The table of :data:`FIELDS` (key, dtype, unit, holds a value on, empty value, meaning); keys quoted with
    ``code``."""
    rows = ["| key | dtype | unit | holds a value on | otherwise | meaning |", "|---|---|---|---|---|---|"]
    rows += [f"| {code}{f.key}{code} | {f.dtype} | {f.unit} | {f.when} | {_shown(empty_value(f), code)} | "
             f"{f.meaning} |" for f in FIELDS]
    return "\n".join(rows)


def estimate_values(est: Estimate) -> dict[str, Any]:
    """The info fields (dotted keys, :mod:`plate_env.env.info`) of an estimate: ``Estimate.to_dict`` with its
    intervals split into their ends, its bound and check in fixed fields, and without the fields whose keys vary
    (the posterior's members, the per-amplitude fits: ``env.unwrapped.estimate()`` has them)."""
    d = est.to_dict()
    v = {f"estimate.{k}": d[k] for k in ("ok", "method", "reason", "forward", "n_probes", "n_unstable")}
    if est.omega_n > 0:  # an answer (a rejected one, ok False, keeps its values); 0: none, empty in the info
        v.update({f"estimate.{k}": d[k] for k in ("omega_n_rad_s", "omega_n_stderr_rad_s", "omega_n_pi")})
        for level in ("68", "95"):
            v[f"estimate.omega_n_ci{level}_lo_rad_s"], v[f"estimate.omega_n_ci{level}_hi_rad_s"] = \
                d[f"omega_n_ci{level}_rad_s"]
    if est.alpha is not None:
        v["estimate.alpha_deg"], v["estimate.alpha_stderr_deg"] = d["alpha_deg"], d["alpha_stderr_deg"]
    if d["bound"] is not None:
        v["estimate.bound.side"], v["estimate.bound.omega_n_rad_s"] = d["bound"]["side"], d["bound"]["omega_n_rad_s"]
    check = d["check"]
    if check is not None:
        v["estimate.check.ok"] = True
        v.update({f"estimate.check.{k}": check[k] for k in ("passed", "statistic", "p_value", "p_min", "n_probes",
                                                            "member")})
        if check["worst"] is not None:
            v.update({f"estimate.check.worst.{k}": x for k, x in check["worst"].items()})
    return v
