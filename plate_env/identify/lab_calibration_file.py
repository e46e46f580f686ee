"""A lab calibration as a file (``plate-env calibrate`` writes it, ``plate-env fit --calibration`` reads it).

CAL.json is one JSON object::

    schema            "plate-env/lab-calibration"        what this file is
    schema_version    3                                    the layout (a reader refuses any other; 1: before the
                                                           feature line, 2: its prior one normal, issue 36)
    package_version   the plate-env version that wrote it  (a reader refuses another version)
    commit            git commit of the writer if known, else null
    inputs_sha256     hash of the references' probes and known omega_n (what it was fitted from)
    forward           the forward model whose members read the sweeps (e.g. "lab")
    members           each member's atlas files (the order the posterior's member indices refer to)
    known             {"a_p_deg", "b_p_mm", "mass_g", "diameter_mm"}: the set-up it holds for; data at another
                      amplitude, B_p, mass or diameter are refused
    references        [{"object", "omega_n_rad_s", "n_probes"}]
    scatter_prior     {"median", "log_sd"}: the prior over the lab's scatter (learned across labs)
    posterior         {"pivot", "member", "a", "b", "sigma", "weight", "n_refs", "ref_range"}: the readings map
    feature_prior     {"components": [{"mean", "cov", "sigma_median", "log_sd"}], "weights", "labels"}: the
                      feature line's mixture prior over labs (learned across labs)
    reference_features  per reference [f0 Hz, omega_Brmax deg/s] of its Lorentzian fit, or null where it failed
    feature_weight    the feature line's weight in the average (the references' leave-one-out evidence)
    assumes           what the calibration assumes, in words
    content_sha256    sha256 of the canonical JSON of every other field: a file edited by hand is refused

Pure apart from :func:`save` and :func:`load`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plate_env.core import checks
from plate_env.core.files import read_json, write_text_atomic
from plate_env.core.probe_table import ProbeTable
from plate_env.identify.adaptive_calibration import (
    FEATURE_PRIOR,
    SCATTER_PRIOR,
    AdaptiveLab,
    FeatureMixture,
    fit_adaptive,
    fit_feature_line,
    hump_features,
    predict_adaptive,
)
from plate_env.identify.estimate import Estimate
from plate_env.identify.forward import ForwardModel, Member, _conditioned
from plate_env.identify.lab_calibration import LabPosterior, ScatterPrior, member_readings
from plate_env.surrogate.catalog import registry_member_atlases
from plate_env.surrogate.conditioning import KnownInputs

SCHEMA = "plate-env/lab-calibration"
SCHEMA_VERSION = 3
#: The priors a calibration ships with (learned across the simulated labs of every shipped physics) are
#: :data:`plate_env.identify.adaptive_calibration.SCATTER_PRIOR` and ``FEATURE_PRIOR`` (imported here).
#: References are refused outside this omega_n range (rad/s): the range every shipped forward model's members cover
#: (the identification prior is 3.5pi-33pi).
REF_RANGE_PI = (3.5, 33.0)
ASSUMES = ("Every disc read with this file is swept on the same plate and set-up as the references (amplitude, "
           "B_p, mass, diameter as recorded). The lab's unknowns are shared by its discs: which member describes the "
           "plate, and a map log omega_n = c + a + (u - c) from that member's reading u, with a scatter sigma "
           "(normal in log omega_n) no member explains; and a line log omega_n = beta . (1, f0 - 26 Hz, "
           "log(omega_Brmax / 600 deg/s)) from the sweep's Lorentzian features with its own scatter. The two are "
           "averaged by the references' leave-one-out evidence. The intervals hold on discs like the references "
           "(the study: experiments/results/calibration_plans.md).")


class CalibrationError(ValueError):
    """A calibration that cannot be made or used: the message names the value and what is allowed."""


@dataclass(frozen=True)
class LabCalibration:
    """What a lab's references taught (see the module docstring for the fields)."""

    forward: str
    members: tuple[tuple[str, ...], ...]
    a_p_deg: float
    known: KnownInputs
    references: tuple[tuple[str, float, int], ...]
    scatter_prior: ScatterPrior
    posterior: LabPosterior
    inputs_sha256: str
    package_version: str
    commit: str | None = None
    feature_prior: FeatureMixture = FEATURE_PRIOR
    reference_features: tuple[tuple[float, float] | None, ...] = ()
    feature_weight: float = 0.5

    def __post_init__(self) -> None:
        if len(self.reference_features) != len(self.references):
            raise CalibrationError(f"reference_features has {len(self.reference_features)} entries for "
                                   f"{len(self.references)} references: one per reference")
        if not (math.isfinite(self.feature_weight) and 0.0 <= self.feature_weight <= 1.0):
            raise CalibrationError(f"feature_weight = {self.feature_weight!r} is outside the allowed range [0, 1]")
        for f in self.reference_features:
            if f is not None and not (len(f) == 2 and all(math.isfinite(x) for x in f) and f[1] > 0):
                raise CalibrationError(f"reference_features entry {f!r}: [f0 Hz, omega_Brmax deg/s > 0] or null")

    def adaptive(self) -> AdaptiveLab:
        """The :class:`~plate_env.identify.adaptive_calibration.AdaptiveLab` of this calibration: the readings
        map's posterior as recorded, the feature line refitted from the recorded references (deterministic)."""
        line = fit_feature_line(self.feature_prior, self.reference_features,
                                [math.log(w) for _, w, _ in self.references])
        return AdaptiveLab(self.posterior, line, self.feature_weight)

    def to_json(self) -> dict:
        post = self.posterior
        body = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "package_version": self.package_version,
                "commit": self.commit, "inputs_sha256": self.inputs_sha256, "forward": self.forward,
                "members": [list(m) for m in self.members],
                "known": {"a_p_deg": self.a_p_deg, "b_p_mm": self.known.b_p * 1e3, "mass_g": self.known.mass * 1e3,
                          "diameter_mm": self.known.diameter * 1e3},
                "references": [{"object": o, "omega_n_rad_s": w, "n_probes": n} for o, w, n in self.references],
                "scatter_prior": {"median": self.scatter_prior.median, "log_sd": self.scatter_prior.log_sd},
                "posterior": {"pivot": post.pivot, "member": list(post.member), "a": list(post.a), "b": list(post.b),
                              "sigma": list(post.sigma), "weight": list(post.weight), "n_refs": post.n_refs,
                              "ref_range": list(post.ref_range)},
                "feature_prior": self.feature_prior.to_json(),
                "reference_features": [None if f is None else list(f) for f in self.reference_features],
                "feature_weight": self.feature_weight,
                "assumes": ASSUMES}
        return {**body, "content_sha256": content_hash(body)}

    @classmethod
    def from_json(cls, d: dict, where: str = "calibration") -> LabCalibration:
        if not isinstance(d, dict) or d.get("schema") != SCHEMA:
            raise CalibrationError(f"{where}: not a plate-env lab calibration (schema {SCHEMA!r})")
        if d.get("schema_version") != SCHEMA_VERSION:
            raise CalibrationError(f"{where}: schema_version {d.get('schema_version')!r}, this plate-env reads "
                                   f"{SCHEMA_VERSION}: run plate-env calibrate again")
        if d.get("package_version") != package_version():
            raise CalibrationError(f"{where}: written by plate-env {d.get('package_version')!r}, this is "
                                   f"{package_version()}: run plate-env calibrate again with this version")
        body = {k: v for k, v in d.items() if k != "content_sha256"}
        if d.get("content_sha256") != content_hash(body):
            raise CalibrationError(f"{where}: content hash does not match (the file was edited by hand or damaged): "
                                   "run plate-env calibrate again")
        k, p = d["known"], d["posterior"]
        a_p_deg = checks.real("known.a_p_deg", k["a_p_deg"], 0.0, 45.0, open_lo=True, unit="deg")
        post = LabPosterior(tuple("+".join(m) for m in d["members"]), float(p["pivot"]), tuple(p["member"]),
                            tuple(p["a"]), tuple(p["b"]), tuple(p["sigma"]), tuple(p["weight"]), int(p["n_refs"]),
                            tuple(p["ref_range"]))
        return cls(forward=d["forward"], members=tuple(tuple(m) for m in d["members"]), a_p_deg=a_p_deg,
                   known=KnownInputs(b_p=k["b_p_mm"] * 1e-3, mass=k["mass_g"] * 1e-3,
                                     diameter=k["diameter_mm"] * 1e-3),
                   references=tuple((r["object"], float(r["omega_n_rad_s"]), int(r["n_probes"]))
                                    for r in d["references"]),
                   scatter_prior=ScatterPrior(**d["scatter_prior"]), posterior=post,
                   inputs_sha256=d["inputs_sha256"], package_version=d["package_version"], commit=d.get("commit"),
                   feature_prior=FeatureMixture.from_json(d["feature_prior"]),
                   reference_features=tuple(None if f is None else (float(f[0]), float(f[1]))
                                            for f in d["reference_features"]),
                   feature_weight=float(d["feature_weight"]))


def package_version() -> str:
    """The installed plate-env's version (the distribution's metadata: plate_env.__version__ lives in the edge
    layer)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("plate-env")
    except PackageNotFoundError:
        return "unknown"


def content_hash(body: dict) -> str:
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def inputs_hash(tables: Sequence[ProbeTable], omega_n: Sequence[float]) -> str:
    h = hashlib.sha256()
    for t, w in zip(tables, omega_n, strict=True):
        h.update(json.dumps({"omega_n": float(w), "probes": t.to_rows()}, sort_keys=True).encode())
    return h.hexdigest()


def lab_members(forward: str, known: KnownInputs) -> tuple[ForwardModel, tuple[tuple[str, ...], ...]]:
    """The members of a shipped forward model that exist for ``known`` (each conditioned on it) and their atlas
    files; CalibrationError when none does."""
    files, members = [], []
    for atlases in registry_member_atlases(forward):
        try:
            atlas = _conditioned(tuple(atlases), known)
        except ValueError:
            continue
        files.append(tuple(atlases))
        members.append(Member(atlas, float(atlas.provenance["sigma_model_deg_s"])))
    if not members:
        raise CalibrationError(f"forward model {forward!r} has no member for B_p {known.b_p * 1e3:g} mm, mass "
                               f"{known.mass * 1e3:g} g, diameter {known.diameter * 1e3:g} mm")
    return ForwardModel(forward, tuple(members)), tuple(files)


def _commit() -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5,
                             cwd=Path(__file__).parent)
        return out.stdout.strip() or None if out.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        return None


def check_references(objects: Sequence[str], omega_n: Sequence[float]) -> None:
    """CalibrationError unless there is at least one reference and every known omega_n is finite and inside
    :data:`REF_RANGE_PI`."""
    if not objects:
        raise CalibrationError("no reference discs: give at least one (K = 1 gives wide intervals; 3 or more fit the "
                               "slope)")
    lo, hi = (x * math.pi for x in REF_RANGE_PI)
    for o, w in zip(objects, omega_n, strict=True):
        if not (math.isfinite(w) and lo <= w <= hi):
            raise CalibrationError(f"reference {o!r}: omega_n_rad_s = {w:g} is outside the identifiable range "
                                   f"{lo:.1f}-{hi:.1f} rad/s ({REF_RANGE_PI[0]:g}pi-{REF_RANGE_PI[1]:g}pi)")


def check_distinct(objects: Sequence[str], omega_n: Sequence[float], tables: Sequence[ProbeTable]) -> None:
    """CalibrationError when two references are one disc under two names: the same known omega_n and the same
    probes (the same rows in any order). Counted twice, one disc would pass for K = 2 independent references and
    narrow the intervals by what it does not know."""
    seen: dict = {}
    for o, w, t in zip(objects, omega_n, tables, strict=True):
        key = (float(w), tuple(sorted(tuple(sorted(r.items())) for r in t.to_rows())))
        if key in seen:
            raise CalibrationError(f"references {seen[key]!r} and {o!r} are the same disc (omega_n_rad_s {w:g} and "
                                   f"identical rows): list each reference disc once")
        seen[key] = o


def calibrate(tables: Sequence[ProbeTable], omega_n: Sequence[float], objects: Sequence[str], a_p_deg: float,
              known: KnownInputs, forward: str = "lab", prior: ScatterPrior = SCATTER_PRIOR,
              feature_prior: FeatureMixture = FEATURE_PRIOR) -> LabCalibration:
    """Fit a lab calibration from reference sweeps of discs of known omega_n (rad/s), all at amplitude
    ``a_p_deg`` and on the set-up ``known``: the readings map and the feature line and the feature line's weight
    (:func:`plate_env.identify.adaptive_calibration.fit_adaptive`)."""
    check_references(objects, omega_n)
    if len(set(objects)) != len(objects):
        raise CalibrationError(f"reference names repeat: {sorted(objects)}; one sweep table per disc")
    check_distinct(objects, omega_n, tables)
    for o, t in zip(objects, tables, strict=True):
        amps = sorted({round(float(a), 6) for a in t.a_p_deg})
        if amps != [round(float(a_p_deg), 6)]:
            raise CalibrationError(f"reference {o!r} has probes at A_p {amps} deg; a calibration holds for one "
                                   f"amplitude (--amp {a_p_deg:g})")
    fm, files = lab_members(forward, known)
    readings = [member_readings(fm, t) for t in tables]
    for o, r in zip(objects, readings, strict=True):
        if not r.available.any():
            raise CalibrationError(f"reference {o!r}: no member of {forward!r} describes its probes")
    feats = [hump_features(t) for t in tables]
    lab = fit_adaptive(readings, feats, np.log(np.asarray(omega_n, dtype=float)), ["+".join(f) for f in files],
                       prior, feature_prior)
    return LabCalibration(forward, files, float(a_p_deg), known,
                          tuple((o, float(w), len(t)) for o, w, t in zip(objects, omega_n, tables, strict=True)),
                          prior, lab.readings, inputs_hash(tables, omega_n), package_version(), _commit(),
                          feature_prior, tuple(feats), lab.feature_weight)


def check_data(cal: LabCalibration, table: ProbeTable, known: KnownInputs) -> None:
    """CalibrationError when the data's amplitude or set-up differ from the calibration's."""
    amps = sorted({round(float(a), 6) for a in table.a_p_deg})
    if amps != [round(cal.a_p_deg, 6)]:
        raise CalibrationError(f"the data have A_p {amps} deg, the calibration holds for A_p = {cal.a_p_deg:g} deg "
                               "only: calibrate at the data's amplitude")
    for name, unit, scale in (("b_p", "mm", 1e3), ("mass", "g", 1e3), ("diameter", "mm", 1e3)):
        a, b = getattr(known, name), getattr(cal.known, name)
        if not math.isclose(abs(a), abs(b), rel_tol=0.02):
            raise CalibrationError(f"the data's {name} = {abs(a) * scale:g} {unit}, the calibration's = "
                                   f"{abs(b) * scale:g} {unit}: calibrate on the data's set-up")


def identify_calibrated(table: ProbeTable, cal: LabCalibration, known: KnownInputs | None = None) -> Estimate:
    """omega_n of a disc read through a lab calibration (an :class:`Estimate`, method ``"calibrated"``)."""
    known = known or cal.known
    check_data(cal, table, known)
    fm, files = lab_members(cal.forward, cal.known)
    if files != cal.members:
        raise CalibrationError(f"the calibration's members {['+'.join(f) for f in cal.members]} are not this "
                               f"plate-env's {['+'.join(f) for f in files]}: run plate-env calibrate again")
    base = {"method": "calibrated", "n_probes": len(table), "n_unstable": int(table.unstable.sum()),
            "forward": f"{cal.forward} calibrated by {len(cal.references)} reference(s)"}
    p = predict_adaptive(cal.adaptive(), member_readings(fm, table), hump_features(table))
    if not p.ok:
        return Estimate(ok=False, reason=p.reason, **base)
    lo, hi = fm.identifiable_range
    if not lo <= p.omega_n <= hi:  # a reading beyond the range the members identify: no number, and no bound
        return Estimate(ok=False, reason=(  # (its physics may not be the references': the tail is not a promise)
            f"the calibrated reading, {p.omega_n / math.pi:.3g} pi rad/s (95 % {p.ci95[0] / math.pi:.3g}-"
            f"{p.ci95[1] / math.pi:.3g} pi), lies outside the range {cal.forward!r} identifies ({lo / math.pi:.3g}-"
            f"{hi / math.pi:.3g} pi rad/s): the references do not reach this disc, so no estimate"), **base)
    return Estimate(ok=True, omega_n=p.omega_n, omega_n_stderr=0.5 * (p.ci68[1] - p.ci68[0]), omega_n_ci68=p.ci68,
                    omega_n_ci95=p.ci95, **base)


def save(cal: LabCalibration, path: str | Path) -> None:
    """Write ``cal`` to ``path`` all at once (a failure leaves an existing file as it was; the error names it)."""
    write_text_atomic(path, json.dumps(cal.to_json(), indent=1) + "\n", "calibration")


#: ``--calibration paper``: the paper's published numbers as the reference set (package data, written by
#: ``python experiments/calibration_study.py paper``).
PAPER = "paper"
PAPER_FILE = "calibration_paper.json"


def load(path: str | os.PathLike[str]) -> LabCalibration:
    """Read CAL.json (or the shipped ``"paper"`` calibration); CalibrationError (naming the file) when it is not
    one, is from another version, or was edited."""
    if str(path) == PAPER:
        from importlib import resources

        path = Path(str(resources.files("plate_env") / "data" / PAPER_FILE))
    try:
        d = read_json(path, "calibration")
    except ValueError as exc:
        raise CalibrationError(str(exc)) from None
    try:
        return LabCalibration.from_json(d, str(path))
    except CalibrationError:
        raise
    except (KeyError, TypeError, ValueError) as exc:  # a field missing, of the wrong type or outside its range
        raise CalibrationError(f"{path}: malformed calibration ({exc})") from None


REF_COLUMNS = ("object", "omega_n_rad_s", "mass_g")


def read_reference_csv(path: str | Path, a_p_deg: float | None = None, max_rows: int | None = None
                       ) -> tuple[list[str], list[float], list, list[float | None]]:
    """A references file: the ``fit`` columns plus ``object`` (a reference disc's name) and ``omega_n_rad_s`` (its
    known omega_n), optionally ``mass_g`` per object. Returns (objects, omega_n, tables, masses in g or None), in
    the order the discs first appear. CalibrationError naming the line for a missing column or an omega_n that
    differs between one disc's rows; the sweep columns are checked by
    :func:`plate_env.core.probe_table.sweep_table` with the file's own line numbers. ``max_rows``: the file (all
    discs together) is refused past that many rows, before any is parsed."""
    from plate_env.core.probe_table import CsvError, check_amp_option, read_csv_rows, sweep_table

    try:
        check_amp_option(a_p_deg)
        header, rows = read_csv_rows(path, max_rows)
    except CsvError as exc:
        raise CalibrationError(str(exc)) from None
    for col in ("object", "omega_n_rad_s"):
        if col not in header:
            raise CalibrationError(f"{path}: line 1: missing column {col!r} (each reference disc's name and its known "
                                   f"omega_n, rad/s); header is {header} (one disc's sweep: give it as "
                                   f"{path}=OMEGA, e.g. {path}=10pi)")
    groups: dict[str, list[tuple[int, list[str]]]] = {}
    omega: dict[str, float] = {}
    mass: dict[str, float | None] = {}
    for lineno, row in rows:
        if len(row) != len(header):
            raise CalibrationError(f"{path}: line {lineno}: {len(row)} fields, the header has {len(header)}")
        cells = dict(zip(header, (c.strip() for c in row), strict=True))
        name = cells["object"]
        if not name:
            raise CalibrationError(f"{path}: line {lineno}: empty object name")
        try:
            w = float(cells["omega_n_rad_s"])
            m = float(cells["mass_g"]) if cells.get("mass_g") else None
        except ValueError:
            raise CalibrationError(f"{path}: line {lineno}: omega_n_rad_s / mass_g must be numbers") from None
        if not (math.isfinite(w) and (m is None or math.isfinite(m))):  # NaN != NaN: refused here, by name
            raise CalibrationError(f"{path}: line {lineno}: omega_n_rad_s = {cells['omega_n_rad_s']!r}, mass_g = "
                                   f"{cells.get('mass_g')!r}: both must be finite numbers")
        if name in omega and (omega[name] != w or mass[name] != m):
            raise CalibrationError(f"{path}: line {lineno}: {name!r} has another omega_n_rad_s or mass_g than on its "
                                   "first row")
        omega.setdefault(name, w)
        mass.setdefault(name, m)
        groups.setdefault(name, []).append((lineno, row))
    tables = []
    for name, body in groups.items():
        try:
            tables.append(sweep_table(path, header, body, a_p_deg=a_p_deg, extra=REF_COLUMNS))
        except CsvError as exc:
            raise CalibrationError(f"{exc} (object {name!r})") from None
    names = list(groups)
    return names, [omega[n] for n in names], tables, [mass[n] for n in names]


def read_references(specs: Sequence[str], a_p_deg: float | None = None, max_rows: int | None = None
                    ) -> tuple[list[str], list[float], list, list[float | None]]:
    """The reference discs of ``plate-env calibrate``, from one or more arguments, each either

    - ``SWEEP.csv=OMEGA``: one disc's sweep (the ``fit`` columns, as ``plate-env sweep --csv`` writes them) and its
      known omega_n (rad/s, or ``10pi``); the disc is named after the file (``SWEEP``), or
    - ``REFS.csv``: a references file of several discs (:func:`read_reference_csv`: columns ``object`` and
      ``omega_n_rad_s``).

    Returns (objects, omega_n rad/s, tables, masses in g or None) in the order given. CalibrationError, naming the
    argument, before any calibration work: no argument, an omega_n that does not parse, a file given twice, a
    references file given with ``=OMEGA`` (its column says it), a disc name that two arguments share (two files of
    one name in different directories: rename one), and past ``max_rows`` rows over all files together."""
    from plate_env.core.probe_table import CsvError, check_amp_option, read_csv_rows, sweep_table
    from plate_env.core.units import parse_omega_n

    if not specs:
        raise CalibrationError("no reference files: give REFS.csv or SWEEP.csv=OMEGA (one per disc)")
    objects: list[str] = []
    omega_n: list[float] = []
    tables: list = []
    masses: list[float | None] = []
    source: dict[str, str] = {}
    files: dict[Path, str] = {}
    for spec in specs:
        path_text, sep, omega_text = str(spec).rpartition("=")
        if not sep or Path(str(spec)).is_file():  # a file whose name holds "=" is a file
            path_text, omega_text = str(spec), None
        path = Path(path_text)
        key = path.resolve()
        if key in files:
            raise CalibrationError(f"{spec!r}: the file {path_text!r} is given twice (also as {files[key]!r}); each "
                                   "reference sweep once")
        files[key] = str(spec)
        if omega_text is None:
            names, omega, tabs, mass = read_reference_csv(path, a_p_deg=a_p_deg, max_rows=max_rows)
        else:
            try:
                w = parse_omega_n(omega_text)
            except ValueError as exc:
                raise CalibrationError(f"{spec!r}: {exc}") from None
            try:
                check_amp_option(a_p_deg)
                header, rows = read_csv_rows(path, max_rows)
                if {"object", "omega_n_rad_s"} & {h.strip() for h in header}:
                    raise CalibrationError(f"{spec!r}: {path_text!r} is a references file (it has the columns object "
                                           "and omega_n_rad_s): give it without '=OMEGA'")
                table = sweep_table(path, header, rows, a_p_deg)
            except CsvError as exc:
                raise CalibrationError(str(exc)) from None
            names, omega, tabs, mass = [path.stem], [w], [table], [None]
        for name in names:
            if name in source:
                raise CalibrationError(f"reference disc {name!r} is in both {source[name]!r} and {str(spec)!r}: "
                                       "each disc once, under one name (a sweep's name is its file's: rename one)")
            source[name] = str(spec)
        objects += names
        omega_n += omega
        tables += tabs
        masses += mass
    total = sum(len(t) for t in tables)
    if max_rows is not None and total > max_rows:
        raise CalibrationError(f"the references hold {total} rows together; at most {max_rows} are read")
    return objects, omega_n, tables, masses
