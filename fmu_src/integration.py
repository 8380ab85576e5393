"""Fixed-step explicit integration inside a communication step (standard library only).

Classical RK4 with the number of sub-steps chosen from the fastest local rate of the
dynamics: rate * h <= STEP_RATE_PRODUCT keeps RK4 far inside its stability region
(|lambda h| < 2.8) and its local error below ~1e-9 of the motion per sub-step.

The work per communication step is bounded: a step whose dynamics would need more than
MAX_SUBSTEPS sub-steps (a very stiff spring, a tiny inertia, a huge speed, or simply a very
long step) raises `SubstepBoundError` before any work is done, so the caller can refuse the step
and keep its state.

The rate rule alone does not bound the energy ledger's error (docs/energy_ledger.md):
`ledger_controlled` checks each communication step against the ledger itself, whose exact
rate of change is zero, so that its change over the step is the integration error itself,
and takes the step again with more sub-steps until that error is within the mechanism's
`ledger_accuracy` times the step's energy throughput plus the ledger's own rounding
(`ledger_tolerance`).

One RK4 for every mechanism: a physics module gives the derivative of its whole state (the
one its `derivatives` returns) and its constraints, and `advance_controlled` (or
`integrate_substeps` under `ledger_controlled`) steps it.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from fmu_src.parameters import DomainError, parameter

S = TypeVar("S", bound=tuple)

STEP_RATE_PRODUCT = 0.05
# At most this many RK4 sub-steps per communication step: about 0.2 s of work for the
# costliest model (a free slider), and 10 s steps of the default mechanisms (rates near
# 10 1/s need 2,000).
MAX_SUBSTEPS = 20_000


# The default of every mechanism's `ledger_accuracy` [1]: the ledger residual a step may add
# per joule of energy throughput (|work| and |energy added|) of the step.
LEDGER_ACCURACY = 1e-9
# The ledger's rounding, as a multiple of the magnitude of what is rounded [1]: one evaluation
# of the terms (a sum of a few terms, each a few operations rounded to half an ulp) per sum of
# |term|, and one sub-step's addition to each cumulative energy per |energy|, with a margin of
# 8 so that the check is never decided by rounding alone (docs/energy_ledger.md).
LEDGER_ROUNDING = 8.0 * sys.float_info.epsilon


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


def ledger_accuracy() -> Any:
    """The `ledger_accuracy` field of a mechanism's Parameters (the same in every one)."""
    return parameter(LEDGER_ACCURACY, "1", "Largest energy-ledger residual a communication "
                     "step may add, per joule of its energy throughput (|work| and |energy "
                     "added|): the RK4 sub-steps are refined until the step meets it",
                     min=1e-15, max=1e-3)


# The ledger at the end of the last step accepted (in any instance): (its state, the
# parameters and event inputs of its terms, the terms' sum and magnitude, the step's
# sub-steps). A step that starts
# from that very state object with the same parameters object and equal event inputs starts
# from those terms (terms depend on nothing else), which saves one evaluation per step. The
# references keep the objects alive, so an identity cannot be reused; one assignment replaces
# the tuple, so a thread reads an old or a new one, never a mix.
_last_ledger: tuple = (None, None, None, 0.0, 0.0, 0)


def ledger_controlled(run: Callable[[int], S], terms: Callable[[S], Sequence[float]],
                      works: Sequence[int], s: S, n: int, dt: float, p: Any,
                      events: tuple = ()) -> S:
    """run(n), the state after the step of dt [s] from s with n RK4 sub-steps, with n raised
    until the energy ledger meets p.ledger_accuracy over the step.

    terms(state): the ledger's signed terms [J], whose sum is constant in the exact solution
    (stored energies, E_loss, minus the works and E_added); works: the indices in the state
    of the cumulative works, the first of the state's cumulative energies (those from works[0]
    on). A step is accepted when the change of the sum is at most `ledger_tolerance`:
    accuracy times the step's throughput (the sum of |change| of each work) plus the
    ledger's rounding. Otherwise it is taken again from s with more sub-steps (RK4's error
    over a step falls as n^-4), at least twice as many; SubstepBoundError beyond
    MAX_SUBSTEPS. The terms depend on the state, the parameters p and the event inputs
    `events` only (see _last_ledger).
    """
    global _last_ledger
    accuracy = p.ledger_accuracy
    last = _last_ledger
    if last[0] is s and last[1] is p and last[2] == events:
        before, magnitude = last[3], last[4]
    else:
        start = terms(s)
        before, magnitude = sum(start), sum(map(abs, start))
    while True:
        new = run(n)
        end = terms(new)
        after, end_magnitude = sum(end), sum(map(abs, end))
        error = abs(after - before)
        throughput = 0.0
        for i in works:   # a loop, not sum() over a list comprehension: no frame of its own
            throughput += abs(new[i] - s[i])
        # the tolerance without its sub-steps' part, which only adds to it, decides most
        # steps without measuring the sub-steps' rounding scale (a terms evaluation per
        # state component)
        if error <= accuracy * throughput + LEDGER_ROUNDING * (magnitude + end_magnitude) or (
                error <= (tolerance := ledger_tolerance(
                    accuracy, throughput, magnitude, end_magnitude, n,
                    substep_rounding_scale(terms, new, after, works[0])))):
            _last_ledger = (new, p, events, after, end_magnitude, n)
            return new
        growth = (error / (0.5 * tolerance)) ** 0.25 if tolerance > 0.0 else math.inf
        n = max(2 * n, math.ceil(n * growth)) if growth < MAX_SUBSTEPS else 2 * n
        if n > MAX_SUBSTEPS:
            raise SubstepBoundError(
                f"the energy ledger's accuracy ledger_accuracy = {accuracy:g} needs more than "
                f"the bound of {MAX_SUBSTEPS} RK4 sub-steps over the step of {dt:.4g} s "
                f"(ledger error {error:.3g} J with {n // 2} or more): take shorter "
                "communication steps, or allow a larger ledger_accuracy")


def ledger_tolerance(accuracy: float, throughput: float, start_magnitude: float,
                     end_magnitude: float, n: int, substep_scale: float) -> float:
    """The ledger change [J] a step of n sub-steps may make: accuracy [1] times its
    throughput [J] plus the ledger's rounding, LEDGER_ROUNDING times the sums of |term| [J]
    at its start and end (one evaluation each) and n times the rounding scale of a sub-step
    [J] (`substep_rounding_scale`). The stored energies are evaluated, not accumulated, so
    their evaluation's rounding does not grow with n."""
    return accuracy * throughput + LEDGER_ROUNDING * (start_magnitude + end_magnitude
                                                      + n * substep_scale)


# Relative size of the finite difference that measures the ledger's slope in a state
# component [1]: far above the evaluation's rounding, far below the curvature's scale.
SLOPE_STEP = 2.0 ** -30


def substep_rounding_scale(terms: Callable[[S], Sequence[float]], state: S, total: float,
                           first_energy: int) -> float:
    """What one sub-step's rounding of the state can move the ledger by, per LEDGER_ROUNDING
    [J]: the sum of |energy| of the cumulative energies (state[first_energy:], each added to
    once), and of |x dL/dx| for each other component x of the state (x rounded to half an
    ulp moves the ledger's sum L by dL/dx times that: |x| times the net generalised force
    for a position, twice the kinetic energy for a speed), dL/dx by a finite difference
    from total = sum(terms(state))."""
    scale = sum(map(abs, state[first_energy:]))
    components = list(state)
    for i in range(first_energy):
        x = components[i]
        step = SLOPE_STEP * (abs(x) if x != 0.0 else 1.0)
        components[i] = x + step
        moved = sum(terms(tuple.__new__(type(state), components)))
        components[i] = x
        scale += abs(x * (moved - total) / step)
    return scale


def accepted_substeps(state: Any) -> int | None:
    """The sub-steps of the last step `ledger_controlled` accepted, if it ended in this very
    state object; None otherwise."""
    last = _last_ledger
    return last[5] if last[0] is state else None


def integrate(f: Callable[[S], S], s: S, dt: float, rate: float,
              constrain: Callable[[S], S] | None = None) -> S:
    """Advance s over dt with RK4 sub-steps; constrain (end stops, locks) runs after each."""
    return integrate_substeps(f, s, dt, substeps(dt, rate), constrain)


def integrate_substeps(f: Callable[[S], S], s: S, dt: float, n: int,
                       constrain: Callable[[S], S] | None = None) -> S:
    """`integrate` with n RK4 sub-steps."""
    h = dt / n
    for _ in range(n):
        s = rk4(f, s, h)
        if constrain is not None:
            s = constrain(s)
    return s


def first_substeps(dt: float, rate: float) -> int:
    """`substeps`, with its call spared for the usual step of one sub-step."""
    return 1 if dt * rate / STEP_RATE_PRODUCT <= 1.0 else substeps(dt, rate)


def advance_controlled(rates: Callable[[Sequence[float]], Sequence[float]],
                       terms: Callable[[S], Sequence[float]], works: Sequence[int], s: S,
                       dt: float, rate: float, p: Any, events: tuple = (),
                       constrain: Callable[[S], S] | None = None) -> S:
    """A mechanism's communication step of dt [s] from s: RK4 over the state's derivative
    rates(state) (`integrate_substeps`, constrain after each sub-step), its sub-steps from
    the dynamics' fastest rate [1/s] (`first_substeps`), raised under `ledger_controlled`
    for the ledger terms(state) of the parameters p and the event inputs."""
    return ledger_controlled(lambda n: integrate_substeps(rates, s, dt, n, constrain), terms,
                             works, s, first_substeps(dt, rate), dt, p, events)
