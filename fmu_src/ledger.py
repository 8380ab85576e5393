"""Energy-ledger events shared by the mechanism physics modules (standard library only).

The ledger of every mechanism (docs/energy_ledger.md): stored energy + E_loss - W_drive -
E_added (- W_worm, - W_adjust) stays constant. This module books the one event the
one-link arms share: a payload that joins or leaves at a communication point, or, for a
continuous-time model, changes continuously.
"""

from __future__ import annotations

import math
from typing import Any, Callable, NamedTuple, TypeVar

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


class PayloadFlow(NamedTuple):
    """Rates [1/s, W, W] that a payload changing continuously adds to a one-link arm's
    equations: the continuous-time limit of `change_payload`."""

    omega_dot: float   # braking of the arm by mass joining from rest [rad/s^2]
    loss: float        # kinetic energy lost as it joins [W]
    added: float       # potential energy joining, kinetic energy leaving [W]


def payload_flow(rate: float, w: float, g: float, theta: float, omega: float,
                 inertia: float) -> PayloadFlow:
    """The terms a payload changing at rate [kg/s] at distance w [m] adds, with the arm at
    theta [rad], omega [rad/s] and moment of inertia [kg m2]: mass joining from rest brakes
    the arm (J omega' gains -rate w^2 omega) and loses 1/2 rate w^2 omega^2; mass leaving
    takes its kinetic energy with it (E_added)."""
    gain, drop = max(rate, 0.0), min(rate, 0.0)
    kinetic = 0.5 * (w * omega) ** 2
    return PayloadFlow(-gain * w * w * omega / inertia, gain * kinetic,
                       rate * g * w * math.cos(theta) + drop * kinetic)


def payload_switch(inertia: Callable[[Any, float, float], tuple]) -> Callable:
    """`switch_inputs` of a one-link arm whose one event input is its payload at distance p.w,
    given the arm's inertia(p, payload, theta) (its first item the moment of inertia about
    the pivot [kg m2]): the payload caught from rest or released (`change_payload`)."""
    def switch_inputs(p: Any, before: Any, after: Any, s: S) -> S:
        """The state just after the payload changes at a communication point."""
        return change_payload(s, before.payload, after.payload, p.w, p.g,
                              lambda payload: inertia(p, payload, s.theta)[0])
    return switch_inputs


def payload_derivatives(arm_rates: Callable[[Any, float, float], Callable],
                        inertia: Callable[[Any, float, float], tuple],
                        state: Callable[..., S]) -> Callable:
    """`derivatives` of a one-link arm whose state is (theta, omega, W_drive, E_loss,
    E_added), given its arm_rates(p, payload, tau_drive), the rates (theta, omega) ->
    (omega', friction loss [W]), its inertia(p, payload, theta) (as for `payload_switch`)
    and its State type."""
    def derivatives(p: Any, u: Any, s: S, rates: Any = None, mode: Any = None) -> S:
        """Time derivative of the state (Lagrange equation) for inputs u that are constant
        or, for a continuous-time model such as the harness's reference, change at `rates`
        (d/dt of the inputs): the continuous limit of switch_inputs (`payload_flow`), a
        payload joining from rest brakes the arm, J omega' gains -payload_rate w^2 omega and
        E_loss 1/2 payload_rate w^2 omega^2; a payload leaving takes its kinetic energy
        (E_added). The arm has one regime: mode is not used."""
        theta, omega = s[0], s[1]
        omega_dot, loss = arm_rates(p, u.payload, u.tau_drive)(theta, omega)
        if rates is None:
            return state(omega, omega_dot, u.tau_drive * omega, loss, 0.0)
        flow = payload_flow(rates.payload, p.w, p.g, theta, omega,
                            inertia(p, u.payload, theta)[0])
        return state(omega, omega_dot + flow.omega_dot, u.tau_drive * omega, loss + flow.loss,
                     flow.added)
    return derivatives


def arm_state_nominals(p: Any) -> tuple[float, ...]:
    """`state_nominals` of a one-link arm's state (theta, omega, W_drive, E_loss, E_added):
    1 rad, 1 rad/s and 1 J (the arms' speeds and energies are of that order)."""
    return (1.0, 1.0, 1.0, 1.0, 1.0)
