"""The paper's plate contact, Eqs. (3)-(4): one implementation for every tile-link model.

Unit reading. The paper gives ``k_contact = 11.86 N/mm`` and ``c_contact = 7.65e-3`` with the penetration ``a``
in mm. We read the law in the paper's mm units, ``f [N] = 11.86 a[mm]^2.2 + 7.65e-3 da/dt[mm/s]``, i.e. in SI
``k = 11.86 * 1000**2.2 N/m^2.2`` and ``c = 7.65 N s/m``. Measured before the project (physics-facts note): this
reading gives a heavily damped contact and a clean resonance-like response, while reading ``c`` in N s/m
(1000x smaller) gives a chattering contact, no clean peak and instability from 16 Hz. With a node mass of
0.26 g the damper's rate ``c/m ~ 3e4 1/s`` is far beyond an explicit step, so the normal force is solved
implicitly in the node's normal velocity.

Friction: Coulomb, opposite the slip velocity, ``mu_s`` while the slip speed is below ``V = 100 mm/s`` and
``mu_k`` above. The paper's ``mu* = 0`` at zero slip is realised as an implicit stick: when the friction
impulse that the static coefficient allows is enough to stop the slip in one step, the slip is stopped
(the friction force is then whatever holds the node, at most ``mu_s f``).

These are plain scalar functions so that numba compiles the same code into every kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Contact stiffness, N / m^2.2 (11.86 N/mm^2.2).
K_CONTACT = 11.86 * 1000.0**2.2
#: Contact damping, N s / m (7.65e-3 N/(mm/s)).
C_CONTACT = 7.65
#: Contact force exponent.
CONTACT_EXPONENT = 2.2
#: Friction transition slip speed V, m/s (100 mm/s).
V_TRANSITION = 0.1
#: Gravity, m/s^2.
GRAVITY = 9.81


@dataclass(frozen=True)
class ContactLaw:
    """The coefficients of the plate contact law (SI): ``k`` N/m^2.2, ``c`` N s/m, ``v_transition`` m/s.

    The defaults are the paper's values (read in its mm units, see the module docstring). They were measured for
    the paper's own set-up; :mod:`~plate_env.physics.nuisance` states the band over which a forward model integrates
    them. """

    k: float = K_CONTACT
    c: float = C_CONTACT
    v_transition: float = V_TRANSITION

    def __post_init__(self) -> None:
        for name in ("k", "c", "v_transition"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"ContactLaw {name} = {value!r} must be a positive finite number")


#: The paper's contact law.
PAPER_CONTACT = ContactLaw()


def spring_force(depth: float, k: float) -> float:
    """The penalty spring of Eq. (3), ``k a^2.2`` (N); 0 without penetration (``depth`` a in m)."""
    if depth <= 0.0:
        return 0.0
    return k * math.exp(CONTACT_EXPONENT * math.log(depth))


def damped_normal_force(f_spring: float, v_normal: float, c: float, inv_mass: float, dt: float) -> float:
    """Normal force (N, >= 0) from the spring force ``f_spring`` (N) and the damper, implicit in the end-of-step
    normal velocity: solves ``f = f_spring - c v'`` with ``v' = v_normal + dt f inv_mass``, then clips adhesion.

    ``v_normal``: relative normal velocity (m/s, positive = separating, so da/dt = -v_normal) before the contact
    force acts; ``inv_mass``: inverse effective mass at the contact. Callers that hold the geometry fixed over
    several solver sweeps evaluate :func:`spring_force` once and call this per sweep.
    """
    if f_spring <= 0.0:
        return 0.0
    f = (f_spring - c * v_normal) / (1.0 + dt * c * inv_mass)
    return f if f > 0.0 else 0.0


def friction_scale(slip_speed: float, f_normal: float, mu_s: float, mu_k: float, v_transition: float,
                   inv_mass: float, dt: float) -> float:
    """Factor ``s`` in [0, 1) that the tangential slip velocity is multiplied by after the friction impulse.

    ``s = 0`` is stick (the static coefficient can stop the slip within the step); otherwise the slip is
    reduced by ``mu dt f inv_mass`` with ``mu = mu_s`` below the transition speed and ``mu_k`` above.
    """
    if f_normal <= 0.0 or slip_speed <= 0.0:
        return 1.0
    mu = mu_s if slip_speed < v_transition else mu_k
    dv = mu * f_normal * dt * inv_mass
    if dv >= slip_speed:
        return 0.0
    return 1.0 - dv / slip_speed


def rest_depth(node_weight: float, k: float = K_CONTACT) -> float:
    """Penetration (m) at which the contact spring carries ``node_weight`` (N)."""
    return (node_weight / k) ** (1.0 / CONTACT_EXPONENT)
