"""Readings of data of unknown origin beyond the identifiable range (issue 37 item 1).

A calibration, Eq. (10) lines or the ``lab`` pool read a lab's sweep whose physics no one names; whether its disc lies
beyond the range the models identify depends on that physics (:mod:`plate_env.identify.identifiability` asks one
model). Here every shipped physics is asked (:func:`physics_readings`), each with every joint/contact value the
``lab`` pool gives it (:func:`family_model`: the point mass's nine members, each extended beyond its range), and says
where it would place the disc (:class:`PhysicsReading`). The rule (:func:`every_rule`): when every physics that
explains the probes places the disc beyond its range, no estimate (and no bound: which physics made the data is not
known); one reading it inside lets the reading stand.

What the rule cannot do: when the physics disagree, the data do not say which made them. A live 100 pi point-mass
sweep is explained by the rigid tiles as a 7.6 pi disc (p 0.85) and by the point mass only beyond 45 pi. The rule
that refuses whenever *some* explaining physics places the disc beyond (answering the bound true under all of them)
meets the contract on such sweeps but loses most in-range readings and states false bounds on point-mass discs whose
joint values no member has; both rules measured on the same sweeps: experiments/results/estimate_contract.md,
section 5 (``python experiments/unknown_origin_rule.py``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from plate_env.core.probe_table import ProbeTable
from plate_env.identify.forward import ForwardModel
from plate_env.surrogate.conditioning import KnownInputs

if TYPE_CHECKING:
    from plate_env.identify.estimate import Estimate
    from plate_env.identify.posterior_state import PosteriorState

#: The shipped physics a reading of data of unknown origin asks (:func:`physics_readings`).
PHYSICS_MODELS = ("tilelink/pointmass", "tilelink/rigid_fast", "pybullet/pybullet")
#: What a physics says about the probes' disc (:attr:`PhysicsReading.kind`).
KINDS = ("inside", "beyond", "unplaced", "silent")


@dataclass(frozen=True)
class PhysicsReading:
    """One shipped physics' statement on a sweep, by the atlas method on its :func:`family_model`.

    ``kind``: ``"inside"`` (an estimate inside its identifiable range, ``ci95`` its 95 % interval, rad/s);
    ``"beyond"`` (the edge rule or the extended-range test places the disc beyond the range: ``bound`` its
    ``("above"|"below", rad/s)``, None when beyond both ends); ``"unplaced"`` (it explains the probes but gives no
    omega_n: alpha at the edge of its friction angles); ``"silent"`` (its predictive check fails, a probe lies
    outside its atlases, it has no member for the known inputs, or it refuses without an extended model to look
    beyond its range: it says nothing). ``reason``: the estimate's reason (None inside); ``p_value``: its
    predictive check's (None without one)."""

    name: str
    kind: str
    ci95: tuple[float, float] | None = None
    bound: tuple[str, float] | None = None
    reason: str | None = None
    p_value: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"PhysicsReading.kind = {self.kind!r}; allowed: {', '.join(KINDS)}")
        if (self.kind == "inside") != (self.ci95 is not None):
            raise ValueError(f"PhysicsReading({self.name!r}): a 95 % interval goes with kind 'inside' only")

    @property
    def explains(self) -> bool:
        return self.kind != "silent"

    def said(self) -> str:
        if self.kind == "inside":
            assert self.ci95 is not None
            lo, hi = self.ci95
            return f"{self.name} reads it inside its range, 95 % [{lo / math.pi:.3g}, {hi / math.pi:.3g}] pi rad/s"
        return f"{self.name}: {self.reason}"


@dataclass(frozen=True)
class Verdict:
    """Why a reading of unknown origin does not stand: ``reason``, and ``bound`` (``("above"|"below", rad/s)``)
    when the rule states one, else None."""

    reason: str
    bound: tuple[str, float] | None = None


def family_model(name: str, known: KnownInputs) -> ForwardModel:
    """The shipped physics ``name`` with every joint/contact value the ``lab`` pool gives it: ``name``'s forward
    model (its discrepancy) with the lab's members of that physics (the point mass: its default and eight other
    joint/contact values; the others: their one member). Loaded once per (name, known inputs), so its extended
    model is built once. ValueError when it has no member for the known inputs."""
    from plate_env.identify.forward import shipped_model

    key = (name, known)
    if key not in _FAMILIES:
        own = shipped_model(name, known)
        try:
            lab = shipped_model("lab", known)
        except ValueError:
            lab = None
        labels = {m.label for m in own.members}
        kin = () if lab is None else tuple(m for m in lab.members if m.label in labels)
        fam = own if len(kin) <= len(own.members) else dataclasses.replace(
            own, name=f"{name} (joint values unknown)", members=kin)
        if len(_FAMILIES) >= 8:
            _FAMILIES.clear()
        _FAMILIES[key] = fam
    return _FAMILIES[key]


#: family_model per (name, known inputs).
_FAMILIES: dict[tuple[str, KnownInputs], ForwardModel] = {}


def _reading(name: str, fm: ForwardModel, est: Estimate) -> PhysicsReading:
    """What ``est`` (the atlas estimate of ``fm``, physics ``name``) says as a :class:`PhysicsReading`."""
    from plate_env.identify.identifiability import extended_model

    p = None if est.check is None else est.check.p_value
    if est.ok:
        return PhysicsReading(name, "inside", ci95=est.omega_n_ci95, p_value=p)
    if est.check is None or not est.check.passed:
        return PhysicsReading(name, "silent", reason=est.reason, p_value=p)  # does not explain them (or cannot read)
    if est.beyond is not None:
        return PhysicsReading(name, "beyond", bound=est.bound, reason=est.reason, p_value=p)
    if extended_model(fm) is None:
        return PhysicsReading(name, "silent", reason=est.reason, p_value=p)
    return PhysicsReading(name, "unplaced", reason=est.reason, p_value=p)


def physics_readings(table: ProbeTable, known: KnownInputs,
                     names: Sequence[str] | None = None) -> tuple[PhysicsReading, ...]:
    """Every shipped physics' statement on ``table`` (:data:`PHYSICS_MODELS` unless ``names``): a fresh
    :class:`ReadingsState` fed the whole table."""
    return ReadingsState(known, names).readings(table)


class ReadingsState:
    """Every shipped physics' statement (:class:`PhysicsReading`, by the atlas method on its :func:`family_model`)
    of a probe table that grows by appended probes (an episode's estimate after each probe): each physics keeps its
    incremental posterior
    (:class:`~plate_env.identify.posterior_state.PosteriorState`, whose estimate equals ``identify_atlas``'s) and
    is fed only the probes added since it last answered; a table that is not an extension of the last one starts
    them over."""

    def __init__(self, known: KnownInputs, names: Sequence[str] | None = None) -> None:
        self.known = known
        self.names = tuple(PHYSICS_MODELS if names is None else names)
        self._states: dict[str, PosteriorState | str] = {}
        self._rows: list[tuple[float, float, float, float, bool]] = []

    def readings(self, table: ProbeTable) -> tuple[PhysicsReading, ...]:
        from plate_env.identify.posterior_state import PosteriorState

        rows = [tuple(r) for r in zip(table.f_p_hz.tolist(), table.a_p_deg.tolist(), table.omega_b_deg_s.tolist(),
                                      table.stderr_deg_s.tolist(), table.unstable.tolist(), strict=True)]
        if rows[:len(self._rows)] != self._rows:  # not the same probes followed by new ones: start over
            self._states.clear()
            self._rows = []
        new = rows[len(self._rows):]
        self._rows = rows
        out = []
        for name in self.names:
            st = self._states.get(name)
            todo = new
            if st is None:
                try:
                    st = PosteriorState(family_model(name, self.known))
                except ValueError as e:  # no member for these known inputs: that physics cannot be asked
                    st = str(e)
                self._states[name] = st
                todo = rows
            if isinstance(st, str):
                out.append(PhysicsReading(name, "silent", reason=st))
                continue
            for r in todo:
                st.add(*r)
            out.append(_reading(name, st.fm, st.estimate()))
        return tuple(out)


def every_rule(readings: Sequence[PhysicsReading]) -> Verdict | None:
    """No estimate, and no bound, when every physics that explains the probes places the disc beyond its range;
    None (the reading stands) when one reads it inside or explains it without placing it, or none explains it
    (the reading's own gate judges data no physics explains)."""
    said = [r for r in readings if r.explains]
    if not said or any(r.kind != "beyond" for r in said):
        return None
    return Verdict("every shipped physics that explains these probes places the disc beyond its range ("
                   + "; ".join(r.said() for r in said) + ")")


#: The rule readings of unknown origin go through (:func:`verdict`).
RULE: Callable[[Sequence[PhysicsReading]], Verdict | None] = every_rule


def verdict(table: ProbeTable, known: KnownInputs, state: ReadingsState | None = None) -> Verdict | None:
    """Why a reading of ``table`` (data of unknown origin) must not stand, by :data:`RULE` over every shipped
    physics' statement, or None; ``state``: the episode's :class:`ReadingsState` (the same statements, fed the new
    probes only)."""
    return RULE(physics_readings(table, known) if state is None else state.readings(table))
