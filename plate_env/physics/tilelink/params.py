"""The per-probe parameter vector shared by every tile-link kernel, and the models' default settings (no numba).

The first ``N_PARAMS`` entries mean the same for every model: the plate motion, the contact law, the object's
friction, the time step, the instability limits, the record cadence and the initial placement. A model appends
its own entries after them. The ``P_*`` indices are defined here only; the kernels read them as ``params.P_*``
(one list: numba freezes a module's integer attribute into the compiled code as a constant, as it does a global).
"""

from __future__ import annotations

import math

import numpy as np

from plate_env.core.probe import ProbeSpec
from plate_env.physics.tilelink import contact

(P_MASS, P_KB, P_KIN, P_CIN, P_MUS, P_MUK, P_DT, P_FREQ, P_AMP, P_BP, P_RAMP, P_VLIM, P_SLIP, P_KC, P_CC,
 P_VT, P_G, P_DEPTH0, P_NSTEPS, P_RECEVERY, P_YAW0, P_U0, P_V0) = range(23)
N_PARAMS = 23

#: Default time step of each tile-link model, s. How far each is from its dt -> 0 value is measured in
#: experiments/results/bench_physics.md (point mass) and experiments/results/bench_models.md (rigid tiles).
DEFAULT_DT = {"pointmass": 2e-4, "rigid": 2e-4, "rigid_limit": 2.5e-5, "rigid_fast": 2.5e-5}

#: Default record interval, s: yaw and centre are recorded about every millisecond of simulated time (a backend
#: option, ``TileLinkPhysics(record_interval_s=...)``; what other intervals cost and save is in
#: experiments/results/bench_savings.md).
DEFAULT_RECORD_INTERVAL_S = 1e-3


def common_vector(spec: ProbeSpec, dt: float, slip_limit: float, node_mass: float, size: int = N_PARAMS,
                  contact_weight: float = 1.0, law: contact.ContactLaw = contact.PAPER_CONTACT,
                  record_interval_s: float = DEFAULT_RECORD_INTERVAL_S) -> np.ndarray:
    """A parameter vector of ``size`` entries with the shared ones filled (SI units).

    ``node_mass``: mass of one node/tile (kg), sets the rest penetration under gravity; ``contact_weight``: the
    share of the per-link contact law ``law`` carried by one contact point (1 for a node, 1/4 for a tile corner);
    ``record_interval_s``: yaw and centre are recorded every ``max(1, round(record_interval_s / dt))`` steps.
    """
    obj, mot = spec.obj, spec.motion
    prm = np.zeros(size)
    prm[P_MASS] = node_mass
    prm[P_MUS] = obj.mu_s
    prm[P_MUK] = obj.mu_k
    prm[P_DT] = dt
    prm[P_FREQ] = mot.freq_hz
    prm[P_AMP] = mot.amp_rad
    prm[P_BP] = mot.b_p
    prm[P_RAMP] = mot.ramp_s
    prm[P_VLIM] = 3.0 * mot.peak_speed(obj.radius) + 1.0
    prm[P_SLIP] = slip_limit
    prm[P_KC] = law.k
    prm[P_CC] = law.c
    prm[P_VT] = law.v_transition
    prm[P_G] = contact.GRAVITY
    prm[P_DEPTH0] = contact.rest_depth(node_mass * contact.GRAVITY * contact_weight, law.k * contact_weight)
    prm[P_NSTEPS] = math.ceil(spec.duration_s / dt - 1e-9)
    prm[P_RECEVERY] = max(1, round(record_interval_s / dt))
    prm[P_YAW0] = spec.initial_yaw
    prm[P_U0], prm[P_V0] = spec.initial_offset
    return prm


def allocate_outputs(prm: np.ndarray) -> dict[str, np.ndarray]:
    """Zeroed output arrays of a batch kernel: yaw/centre traces sized for the longest probe, status, records."""
    n_rec = (prm[:, P_NSTEPS] // prm[:, P_RECEVERY]).astype(np.int64) + 1
    size = (len(prm), int(n_rec.max()))
    return {"prm": prm, "yaw": np.zeros(size), "cu": np.zeros(size), "cv": np.zeros(size),
            "status": np.zeros(len(prm), dtype=np.int64), "nrec": np.zeros(len(prm), dtype=np.int64)}
