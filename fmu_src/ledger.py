"""Energy-ledger events shared by the mechanism physics modules (standard library only).

The ledger of every mechanism (docs/energy_ledger.md): stored energy + E_loss - W_drive -
E_added (- W_worm, - W_adjust) stays constant. This module books the one event the
one-link arms share: a payload that joins or leaves at a communication point.
"""

from __future__ import annotations

import math
from typing import Callable, TypeVar

# a NamedTuple state with fields theta [rad], omega [rad/s], E_loss [J] and E_added [J]
S = TypeVar("S")


def change_payload(s: S, before: float, after: float, w: float, g: float,
                   inertia: Callable[[float], float]) -> S:
    """The state just after the payload at distance w [m] from the pivot changes from before
    to after [kg] at the link angle s.theta; inertia(payload) is the link's moment of
    inertia about the pivot [kg m2] there.

    A payload added is picked up from rest: the angular momentum J omega is conserved and
    the kinetic energy lost goes to E_loss. A payload removed leaves with its own velocity
    (omega unchanged) and takes its kinetic energy away. Its potential energy, m g w cos
    theta, joins or leaves through E_added.
    """
    added = after - before
    if added == 0.0:
        return s
    potential = added * g * w * math.cos(s.theta)
    if added > 0.0:
        J_before, J_after = inertia(before), inertia(after)
        omega = s.omega * J_before / J_after
        lost = 0.5 * (J_before * s.omega ** 2 - J_after * omega ** 2)
        return s._replace(omega=omega, E_loss=s.E_loss + lost, E_added=s.E_added + potential)
    kinetic = 0.5 * added * (w * s.omega) ** 2
    return s._replace(E_added=s.E_added + potential + kinetic)
