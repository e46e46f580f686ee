"""The observation and action layout of PlateRotation-v0: one codec for the env and for agents that act from its
observation (the shipped PPO policy, plate_env_agents.ppo), so that a change to the layout changes both.

Action: 4 numbers in [-1, 1]: the plate frequency over the band, the amplitude (the range cut into one equal slice
per amplitude), the measuring window over its range, and stop (> 0 ends the episode, ignored before the first
probe).

Observation: one row of :data:`N_FEATURES` per probe slot (``max_probes`` slots), then the fraction of probes left
and the fraction of simulated seconds left (1 without a budget). A row: frequency over the band, the amplitude's
code (the centre of its slice; 0 with one amplitude), omega_B / 1000 (deg/s, clipped to [-10, 10]), its standard
error / 1000 (clipped to [0, 10]), unstable (0/1), the window over its range, 1 (the slot is filled). Empty slots
are zeros; the whole observation is clipped to [-10, 10].

A :class:`Codec` is the layout for one band, set of amplitudes, window range and slot count; :meth:`Codec.rows_from`
and :meth:`Codec.action_from` translate rows and actions between two codecs through physical units (Hz, deg, s).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

#: Features per probe row of the observation.
N_FEATURES = 7
#: Length of an action.
ACTION_SIZE = 4


def unit(x, lo: float, hi: float):
    """A physical value -> its [-1, 1] coordinate over (lo, hi) (float64)."""
    return 2 * (np.asarray(x, dtype=np.float64) - lo) / (hi - lo) - 1


def _clip(x: float, lo: float, hi: float) -> float:
    """``np.clip(x, lo, hi)``'s value for one float (NaN stays NaN, -0.0 stays -0.0)."""
    return min(max(x, lo), hi) if x == x else x


def phys(u, lo: float, hi: float):
    """A [-1, 1] coordinate over (lo, hi) -> the physical value (float64)."""
    return lo + (np.asarray(u, dtype=np.float64) + 1) / 2 * (hi - lo)


@dataclass(frozen=True)
class Codec:
    """The layout of one env's observations and actions (band Hz, amplitudes deg, window range s, slots)."""

    f_band_hz: tuple[float, float]
    amplitudes_deg: tuple[float, ...]
    measure_range_s: tuple[float, float]
    max_probes: int

    @classmethod
    def of(cls, settings) -> Codec:
        """The codec of an env, a :class:`~plate_env.env.protocol.ProbeContext` or anything with the same four
        attributes."""
        return cls(tuple(settings.f_band_hz), tuple(settings.amplitudes_deg), tuple(settings.measure_range_s),
                   int(settings.max_probes))

    @property
    def obs_dim(self) -> int:
        """The observation's length: one row per slot, then probes left and simulated seconds left."""
        return N_FEATURES * self.max_probes + 2

    @staticmethod
    def slots_of(obs_dim: int) -> int:
        """The slot count of an observation of length ``obs_dim`` (ValueError if no layout has that length)."""
        if obs_dim < 2 or (obs_dim - 2) % N_FEATURES:
            raise ValueError(f"observation of length {obs_dim} is not a PlateRotation-v0 observation")
        return (obs_dim - 2) // N_FEATURES

    def same_coordinates(self, other: Codec) -> bool:
        """Whether ``other`` has this band, amplitudes and window range (to float tolerance): rows and actions
        then need no translation between the two (their slot counts may differ)."""
        return (np.allclose(other.f_band_hz, self.f_band_hz) and len(other.amplitudes_deg) == len(self.amplitudes_deg)
                and np.allclose(other.amplitudes_deg, self.amplitudes_deg)
                and np.allclose(other.measure_range_s, self.measure_range_s))

    # ------------------------------------------------------------------ amplitudes
    def amp_code(self, k: int) -> float:
        """The coordinate of amplitude ``k``: the centre of its slice of [-1, 1] (0 with one amplitude)."""
        n = len(self.amplitudes_deg)
        return (2 * k + 1) / n - 1 if n > 1 else 0.0

    def amp_index(self, u: float) -> int:
        """The amplitude whose slice holds coordinate ``u``."""
        n = len(self.amplitudes_deg)
        return min(int((u + 1) / 2 * n), n - 1)

    def nearest_amp(self, a_p_deg: float) -> int:
        """The index of the amplitude nearest ``a_p_deg`` (the first of equals; 0 for NaN, as np.argmin)."""
        dist = [abs(float(a) - float(a_p_deg)) for a in self.amplitudes_deg]
        return 0 if dist[0] != dist[0] else dist.index(min(dist))

    # ------------------------------------------------------------------ actions
    def decode(self, action: np.ndarray) -> tuple[float, float, float]:
        """A checked action (float64, in [-1, 1]) -> (f_p Hz, A_p deg, window s). Stop is the caller's (a[3] > 0)."""
        (f_lo, f_hi), (w_lo, w_hi) = self.f_band_hz, self.measure_range_s
        # phys()'s operations on Python floats (the same floats, without numpy's per-call cost)
        f = f_lo + (float(action[0]) + 1) / 2 * (f_hi - f_lo)
        window = w_lo + (float(action[2]) + 1) / 2 * (w_hi - w_lo)
        return f, self.amplitudes_deg[self.amp_index(action[1])], window

    def encode(self, f_p_hz: float, a_p_deg: float, measure_s: float, stop: float = -1.0) -> np.ndarray:
        """The action (float32) of a probe at ``f_p_hz`` (clipped to the band), amplitude ``a_p_deg`` (one of the
        amplitudes: ValueError otherwise) and window ``measure_s`` (clipped to the range); ``stop`` as given."""
        if not any(abs(a_p_deg - a) < 1e-9 for a in self.amplitudes_deg):
            raise ValueError(f"A_p = {a_p_deg!r} deg is not one of this env's amplitudes {self.amplitudes_deg}")
        f = unit(np.clip(f_p_hz, *self.f_band_hz), *self.f_band_hz)
        m = unit(np.clip(measure_s, *self.measure_range_s), *self.measure_range_s)
        return np.array([f, self.amp_code(self.nearest_amp(a_p_deg)), m, stop], dtype=np.float32)

    def action_from(self, action: np.ndarray, source: Codec) -> np.ndarray:
        """An action in ``source``'s coordinates as this codec's: frequency and window through Hz and s (clipped
        to this band and range), the amplitude the nearest of this codec's; stop unchanged."""
        if self.same_coordinates(source):
            return action
        f = float(np.clip(phys(action[0], *source.f_band_hz), *self.f_band_hz))
        k = self.nearest_amp(source.amplitudes_deg[source.amp_index(action[1])])
        win = float(np.clip(phys(action[2], *source.measure_range_s), *self.measure_range_s))
        out = np.array([unit(f, *self.f_band_hz), self.amp_code(k), unit(win, *self.measure_range_s), action[3]],
                       dtype=np.float32)
        return np.clip(out, -1.0, 1.0)

    # ------------------------------------------------------------------ observations
    def row(self, f_p_hz: float, a_p_deg: float, omega_b_deg_s: float, stderr_deg_s: float, unstable: bool,
            measure_s: float) -> tuple[float, ...]:
        """One probe's observation row."""
        (f_lo, f_hi), (w_lo, w_hi) = self.f_band_hz, self.measure_range_s
        # unit() and np.clip's values on Python floats (np.clip keeps -0.0 and NaN, as _clip does)
        return (2 * (float(f_p_hz) - f_lo) / (f_hi - f_lo) - 1, self.amp_code(self.nearest_amp(a_p_deg)),
                _clip(float(omega_b_deg_s) / 1000.0, -10.0, 10.0), _clip(float(stderr_deg_s) / 1000.0, 0.0, 10.0),
                float(unstable), 2 * (float(measure_s) - w_lo) / (w_hi - w_lo) - 1, 1.0)

    def observation(self, rows: Iterable[Sequence[float]], probes_left: float, sim_left: float) -> np.ndarray:
        """The observation (float32) of the probes ``rows`` (f_p Hz, A_p deg, omega_B deg/s, its standard error,
        unstable, window s; the first ``max_probes``), the fraction of probes left and of simulated seconds left."""
        obs = np.zeros(self.obs_dim, dtype=np.float32)
        for i, r in enumerate(list(rows)[: self.max_probes]):
            self.put_row(obs, i, r)
        return self.completed(obs, probes_left, sim_left)

    def put_row(self, obs: np.ndarray, i: int, r: Sequence[float]) -> None:
        """Write probe ``r`` (the fields of :meth:`observation`'s rows) as row ``i`` of the observation buffer
        ``obs`` (an env writes each probe's row once, as it arrives)."""
        obs[N_FEATURES * i: N_FEATURES * (i + 1)] = self.row(*r[:6])

    def completed(self, obs: np.ndarray, probes_left: float, sim_left: float) -> np.ndarray:
        """The observation of a buffer of rows (:meth:`put_row`): a new array with the fraction of probes left and
        of simulated seconds left, clipped to [-10, 10]; ``obs`` is not changed."""
        out = obs.copy()
        out[-2] = probes_left
        out[-1] = sim_left
        return np.clip(out, -10.0, 10.0)

    def resized(self, obs: np.ndarray, n_probes: int) -> np.ndarray:
        """An observation of another slot count laid out in this one: the filled rows copied (up to this codec's
        slots), the probes left recomputed against them, the simulated seconds left passed through."""
        obs = np.asarray(obs, dtype=np.float32).ravel()
        if obs.shape[0] == self.obs_dim:
            return obs
        n = min(n_probes, self.max_probes, self.slots_of(obs.shape[0]))
        out = np.zeros(self.obs_dim, dtype=np.float32)
        out[: N_FEATURES * n] = obs[: N_FEATURES * n]
        out[-2] = max(1.0 - n_probes / self.max_probes, 0.0)
        out[-1] = obs[-1]
        return out

    def rows_from(self, obs: np.ndarray, n: int, source: Codec) -> np.ndarray:
        """An observation whose first ``n`` rows are in ``source``'s coordinates with those rows re-expressed in
        this codec's (frequency and window through Hz and s, the amplitude the nearest of this codec's)."""
        if n == 0 or self.same_coordinates(source):
            return obs
        rows = obs[: N_FEATURES * n].reshape(n, N_FEATURES).astype(np.float64)
        k_src = np.clip(np.floor((rows[:, 1] + 1) / 2 * len(source.amplitudes_deg)), 0,
                        len(source.amplitudes_deg) - 1).astype(int)
        f = phys(rows[:, 0], *source.f_band_hz)
        win = phys(rows[:, 5], *source.measure_range_s)
        rows[:, 0] = unit(f, *self.f_band_hz)
        rows[:, 1] = [self.amp_code(self.nearest_amp(source.amplitudes_deg[i])) for i in k_src]
        rows[:, 5] = unit(win, *self.measure_range_s)
        out = obs.copy()
        out[: N_FEATURES * n] = np.clip(rows, -10, 10).ravel()
        return out


__all__ = ["ACTION_SIZE", "N_FEATURES", "Codec", "phys", "unit"]
