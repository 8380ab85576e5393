"""Fixed-step explicit integration inside a communication step (standard library only).

Classical RK4 with the number of sub-steps chosen from the fastest local rate of the
dynamics: rate * h <= STEP_RATE_PRODUCT keeps RK4 far inside its stability region
(|lambda h| < 2.8) and its local error below ~1e-9 of the motion per sub-step.

The work per communication step is bounded: a step whose dynamics would need more than
MAX_SUBSTEPS sub-steps (a very stiff spring, a tiny inertia, a huge speed, or simply a very
long step) raises `SubstepBoundError` before any work is done, so the caller can refuse the step
and keep its state.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TypeVar

from fmu_src.parameters import DomainError

S = TypeVar("S", bound=tuple)

STEP_RATE_PRODUCT = 0.05
# At most this many RK4 sub-steps per communication step: about 0.2 s of work for the
# costliest model (a free slider), and 10 s steps of the default mechanisms (rates near
# 10 1/s need 2,000).
MAX_SUBSTEPS = 20_000


class SubstepBoundError(DomainError):
    """The dynamics need more sub-steps over the communication step than MAX_SUBSTEPS."""


def rk4(f: Callable[[Sequence[float]], Sequence[float]], s: S, h: float) -> S:
    """One classical Runge-Kutta step of size h for ds/dt = f(s); s is a NamedTuple.

    f gets the intermediate states as plain lists (it reads them by position): building a
    NamedTuple per stage cost more than the arithmetic. The result is of s's type (built by
    tuple.__new__: s's _make is a Python call).
    """
    half, sixth = 0.5 * h, h / 6.0
    k1 = f(s)
    k2 = f([si + half * ki for si, ki in zip(s, k1)])
    k3 = f([si + half * ki for si, ki in zip(s, k2)])
    k4 = f([si + h * ki for si, ki in zip(s, k3)])
    return tuple.__new__(type(s), [si + sixth * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
                                   for si, d1, d2, d3, d4 in zip(s, k1, k2, k3, k4)])


def substeps(dt: float, rate: float) -> int:
    """Number of RK4 sub-steps for a step dt [s] of dynamics whose fastest rate is rate [1/s].

    Raises SubstepBoundError when that exceeds MAX_SUBSTEPS (or the rate is not a number).
    """
    needed = dt * rate / STEP_RATE_PRODUCT
    if not needed <= MAX_SUBSTEPS:  # also NaN and inf
        raise SubstepBoundError(
            f"the dynamics' fastest rate {rate:.4g} 1/s needs {needed:.4g} RK4 sub-steps over "
            f"the step of {dt:.4g} s, more than the bound of {MAX_SUBSTEPS}: take shorter "
            "communication steps, or check the stiffness, damping, inertia and speed")
    return max(1, math.ceil(needed))


def integrate(f: Callable[[S], S], s: S, dt: float, rate: float,
              constrain: Callable[[S], S] | None = None) -> S:
    """Advance s over dt with RK4 sub-steps; constrain (end stops, locks) runs after each."""
    n = substeps(dt, rate)
    h = dt / n
    for _ in range(n):
        s = rk4(f, s, h)
        if constrain is not None:
            s = constrain(s)
    return s


def integrate_arm(f: Callable[[float, float], tuple[float, float]], theta: float, omega: float,
                  W_drive: float, E_loss: float, tau: float, dt: float, rate: float
                  ) -> tuple[float, float, float, float]:
    """Advance a one-link arm over dt [s] with RK4 sub-steps: theta' = omega,
    (omega', E_loss') = f(theta, omega) and W_drive' = tau omega for a drive torque tau held
    over the step; returns (theta, omega, W_drive, E_loss).

    The same numbers as `integrate` over the state (theta, omega, W_drive, E_loss), bit for
    bit, with the stages kept in local floats: one call of f per stage and no tuple per
    stage, where the tuples and calls cost more than the arm's arithmetic.
    """
    # one sub-step for the usual step (substeps' answer then, without its call)
    n = 1 if dt * rate / STEP_RATE_PRODUCT <= 1.0 else substeps(dt, rate)
    h = dt / n
    half, sixth = 0.5 * h, h / 6.0
    for _ in range(n):
        a1, l1 = f(theta, omega)
        o2 = omega + half * a1
        a2, l2 = f(theta + half * omega, o2)
        o3 = omega + half * a2
        a3, l3 = f(theta + half * o2, o3)
        o4 = omega + h * a3
        a4, l4 = f(theta + h * o3, o4)
        W_drive += sixth * (tau * omega + 2.0 * (tau * o2) + 2.0 * (tau * o3) + tau * o4)
        E_loss += sixth * (l1 + 2.0 * l2 + 2.0 * l3 + l4)
        theta += sixth * (omega + 2.0 * o2 + 2.0 * o3 + o4)
        omega += sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return theta, omega, W_drive, E_loss
