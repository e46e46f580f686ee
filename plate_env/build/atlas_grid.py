"""An atlas grid as data, its probes, and running them resumably on any executor (the atlas build's engine).

    grid = AtlasGrid.from_json("grid.json")       # or AtlasGrid(f_hz=(10, 11, ...), a_p_deg=(3,), ...)
    results = run_grid(BackendSpec.of("tilelink", model="rigid_limit"), grid, repeats=2, seed=0,
                       cache="experiments/cache/atlas_x.jsonl", executor="ray")

``results`` is an object array shaped (n_f, n_a, n_omega, n_alpha, repeats) of :class:`ProbeResult`, ready for
:func:`plate_env.surrogate.atlas.atlas_from_repeats`. Used by :mod:`plate_env.build.atlas` (``plate-env build atlas``).

A grid file is JSON with ``f_p_hz``, ``a_p_deg``, ``omega_n_pi`` (units of pi rad/s), ``alpha_deg`` (lists of
numbers; ``f_p_hz`` may also be ``"start:stop:step"``, inclusive) and optionally ``settle_s``, ``measure_s`` and the
known inputs the atlas is built at, ``mass_g``, ``b_p_mm``, ``diameter_mm`` (default the paper's 13.6 g, 3 mm,
80 mm).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plate_env.core.motion import PlateMotion
from plate_env.core.objects import ObjectSpec
from plate_env.core.probe import ProbeSpec
from plate_env.core.setup import PAPER_SETUP
from plate_env.run.executor import BackendSpec, Executor
from plate_env.run.sweeps import run_cached


def _axis(name: str, values) -> tuple[float, ...]:
    if isinstance(values, str):
        try:
            start, stop, step = (float(p) for p in values.split(":"))
        except ValueError:
            raise ValueError(f"grid {name} = {values!r}: expected start:stop:step") from None
        if not (step > 0 and stop >= start):
            raise ValueError(f"grid {name} = {values!r}: needs step > 0 and stop >= start")
        values = np.arange(start, stop + 1e-9 * step, step)
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ValueError(f"grid {name} = {values!r}: expected a list of numbers") from None
    if not out or not all(math.isfinite(v) and v > 0 for v in out):
        raise ValueError(f"grid {name} = {values!r}: needs at least one positive finite value")
    if any(b <= a for a, b in zip(out, out[1:], strict=False)):
        raise ValueError(f"grid {name} = {out}: values must increase")
    return out


@dataclass(frozen=True)
class AtlasGrid:
    """A probe grid: plate frequencies (Hz) x amplitudes (deg) x omega_n (pi rad/s) x alpha (deg), the probe
    windows (s, after the 0.2 s ramp) and the known inputs every probe shares (the disc's mass in g and diameter in
    mm, the plate's B_p in mm). Axes are increasing tuples of positive numbers (checked)."""

    f_hz: tuple[float, ...]
    a_p_deg: tuple[float, ...]
    omega_n_pi: tuple[float, ...]
    alpha_deg: tuple[float, ...]
    settle_s: float = 0.5
    measure_s: float = 1.0
    mass_g: float = PAPER_SETUP.mass_g
    b_p_mm: float = PAPER_SETUP.b_p_mm
    diameter_mm: float = PAPER_SETUP.diameter_mm

    def __post_init__(self) -> None:
        for name in ("f_hz", "a_p_deg", "omega_n_pi", "alpha_deg"):
            object.__setattr__(self, name, _axis(name, getattr(self, name)))
        self.spec(0, 0, 0, 0)  # the windows', the known inputs' and the lowest frequency's checks

    def spec(self, i_f: int, i_a: int, i_w: int, i_al: int) -> ProbeSpec:
        """The centred probe at one grid point."""
        obj = ObjectSpec.from_paper(self.omega_n_pi[i_w], self.alpha_deg[i_al], mass_g=self.mass_g,
                                    diameter_mm=self.diameter_mm)
        return ProbeSpec(obj, PlateMotion.from_paper(self.f_hz[i_f], self.a_p_deg[i_a], self.b_p_mm),
                         settle_s=self.settle_s, measure_s=self.measure_s)

    @classmethod
    def from_dict(cls, d: dict) -> AtlasGrid:
        known = {"f_p_hz", "a_p_deg", "omega_n_pi", "alpha_deg", "settle_s", "measure_s", "mass_g", "b_p_mm",
                 "diameter_mm"}
        if unknown := set(d) - known:
            raise ValueError(f"grid: unknown keys {sorted(unknown)}; expected {sorted(known)}")
        if missing := {"f_p_hz", "a_p_deg", "omega_n_pi", "alpha_deg"} - set(d):
            raise ValueError(f"grid: missing keys {sorted(missing)}")
        return cls(f_hz=d["f_p_hz"], a_p_deg=d["a_p_deg"], omega_n_pi=d["omega_n_pi"], alpha_deg=d["alpha_deg"],
                   settle_s=float(d.get("settle_s", 0.5)), measure_s=float(d.get("measure_s", 1.0)),
                   mass_g=float(d.get("mass_g", PAPER_SETUP.mass_g)), b_p_mm=float(d.get("b_p_mm", PAPER_SETUP.b_p_mm)),
                   diameter_mm=float(d.get("diameter_mm", PAPER_SETUP.diameter_mm)))

    @classmethod
    def from_json(cls, path: str | Path) -> AtlasGrid:
        try:
            d = json.loads(Path(path).read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"grid file {path}: not JSON ({exc})") from None
        if not isinstance(d, dict):
            raise ValueError(f"grid file {path}: expected a JSON object")
        return cls.from_dict(d)

    def to_dict(self) -> dict:
        return {"f_p_hz": list(self.f_hz), "a_p_deg": list(self.a_p_deg), "omega_n_pi": list(self.omega_n_pi),
                "alpha_deg": list(self.alpha_deg), "settle_s": self.settle_s, "measure_s": self.measure_s,
                "mass_g": self.mass_g, "b_p_mm": self.b_p_mm, "diameter_mm": self.diameter_mm}

    def shape(self, repeats: int) -> tuple[int, int, int, int, int]:
        return (len(self.f_hz), len(self.a_p_deg), len(self.omega_n_pi), len(self.alpha_deg), repeats)


def grid_probes(grid: AtlasGrid, repeats: int, rng: np.random.Generator, placed: bool = True,
                sweeps: bool = False) -> tuple[list[tuple[int, ...]], list[ProbeSpec]]:
    """The grid's probes and their grid indices ``(i_f, i_a, i_omega, i_alpha, i_repeat)``.

    Order: ``np.ndindex`` (f_p outermost), or with ``sweeps`` object-major with ascending f_p innermost (a backend
    that carries state over a sequence of one object's probes, PyBullet). With ``placed`` each probe is placed by
    ``ProbeSpec.perturbed(rng)`` in that order (one draw sequence from ``rng``), else centred.
    """
    if not (isinstance(repeats, int) and repeats >= 1):
        raise ValueError(f"repeats = {repeats!r} must be a positive int")
    order = list(np.ndindex(grid.shape(repeats)))
    if sweeps:
        order.sort(key=lambda ix: (ix[2], ix[3], ix[1], ix[4], ix[0]))
    specs = []
    for i_f, i_a, i_w, i_al, _ in order:
        base = grid.spec(i_f, i_a, i_w, i_al)
        specs.append(base.perturbed(rng) if placed else base)
    return order, specs


def run_grid(backend: BackendSpec, grid: AtlasGrid, repeats: int, seed: int, cache: str | Path | None,
             executor: Executor | str | None = None, chunk: int | None = None, placed: bool = True,
             sweeps: bool = False, progress: bool = True, desc: str = "atlas",
             nodes: tuple[Sequence[int], ...] | None = None) -> np.ndarray:
    """Every grid probe's result (object array shaped ``grid.shape(repeats)``), run through ``executor`` with the
    resumable cache (:func:`plate_env.run.sweeps.run_cached`). ``chunk`` defaults to one sweep (``len(grid.f_hz)``)
    with ``sweeps``, else 128 in-process and 16 on workers (many chunks to spread, each still a batch).

    ``nodes``: only the nodes at these indices per axis (f, A_p, omega_n, alpha), each probe placed as in the whole
    grid's build (the placements are drawn for every probe in grid order, the others are not run); the result is
    shaped by the selection."""
    order, specs = grid_probes(grid, repeats, np.random.default_rng(seed), placed=placed, sweeps=sweeps)
    shape = grid.shape(repeats)
    if nodes is not None:
        if len(nodes) != 4:
            raise ValueError(f"nodes: expected index lists for 4 axes (f, A_p, omega_n, alpha), got {len(nodes)}")
        where = [{i: k for k, i in enumerate(ix)} for ix in nodes]
        kept = [(tuple(w[i] for w, i in zip(where, ix[:4], strict=True)) + ix[4:], s)
                for ix, s in zip(order, specs, strict=True) if all(i in w for w, i in zip(where, ix[:4], strict=True))]
        order, specs = [k for k, _ in kept], [s for _, s in kept]
        shape = (*map(len, nodes), repeats)
    if chunk is None:
        in_process = executor in (None, "inprocess") or getattr(executor, "name", "") == "inprocess"
        if executor in (None, "local"):
            from plate_env.run.executor import default_local

            in_process = default_local(backend) == "inprocess"
        chunk = len(grid.f_hz) if sweeps else (128 if in_process else 16)
    results = run_cached(backend, specs, cache, chunk=chunk, progress=progress, desc=desc, executor=executor)
    out = np.empty(shape, dtype=object)
    for idx, r in zip(order, results, strict=True):
        out[idx] = r
    return out


def result_arrays(results: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(omega_B deg/s, its standard error deg/s, unstable) arrays of a :func:`run_grid` result array."""
    def pick(attr: str, kind: type) -> np.ndarray:
        return np.vectorize(lambda r: getattr(r, attr), otypes=[kind])(results)

    return pick("omega_b_deg_s", float), pick("stderr_deg_s", float), pick("unstable", bool)


__all__: Sequence[str] = ("AtlasGrid", "grid_probes", "result_arrays", "run_grid")
