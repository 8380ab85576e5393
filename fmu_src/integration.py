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

The RK4 kernels, one per state shape; a physics module gives rates (and events) and calls
one of them. All but `rk4` keep the stages in local floats, because a call and a tuple per
stage cost more than a small model's arithmetic, and each gives the numbers of `rk4` over its
full state bit for bit (tests/test_integration.py):
- `rk4`, `integrate`, `integrate_substeps`: any state, a derivative of the whole state;
- `integrate_arm`: a one-link arm (theta, omega, W_drive, E_loss) with rates f(theta, omega);
- `integrate_sine_arm`: the same arm of constant inertia with sinusoidal gravity and spring
  moments, written out with no call per stage;
- `integrate_link_slider`: a link with a slider along it and a body the slider drives;
- `rk4_link_carriage_step`: one step of a link with a force-driven carriage whose regime
  (a self-locking screw's) is held through the step.

They pay their way (docs/performance.md, "Speed code measured against the 10 % rule"):
replacing them, the arms' `_arm_rates`, the active spring's `_stage_rates` and memo.py's
slots by `rk4` over each mechanism's `derivatives` (same results, bit for bit) added, in
callgrind instructions per FMU step, 112 k to the self-regulating balancer's locked step (87 k),
149 k to its free slider's (229 k), 111 k to CiupituBalancer's (108 k), 153 k to the rocking
counterweight's (238 k) and 78 k to ActiveSpringBalancer's (143 k), 36 to 69 % of a closed-loop
step (the FMU step and the master's 75 k); measured over whole closed-loop runs, 117 k to
franchetti2021 self_regulating's step (173 k) and 160 k to unregulated's (162 k): 68 and 99 %.
In all, 36 to 99 % of a closed-loop step.
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


def integrate_arm(f: Callable[[float, float], tuple[float, float]], theta: float, omega: float,
                  W_drive: float, E_loss: float, tau: float, dt: float, n: int
                  ) -> tuple[float, float, float, float]:
    """Advance a one-link arm over dt [s] with RK4 sub-steps: theta' = omega,
    (omega', E_loss') = f(theta, omega) and W_drive' = tau omega for a drive torque tau held
    over the step with n sub-steps; returns (theta, omega, W_drive, E_loss).

    The same numbers as `integrate_substeps` over the state (theta, omega, W_drive, E_loss),
    bit for bit, with the stages kept in local floats: one call of f per stage and no tuple
    per stage, where the tuples and calls cost more than the arm's arithmetic.
    """
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


def rk4_link_carriage_step(rates: Callable[..., tuple[float, float, float]], tau: float,
                           force: float, s: S, h: float) -> S:
    """One RK4 step of size h [s] from s for a link and a driven carriage, the state
    (theta, omega, q, q_dot, W_drive, W_force, E_loss, E_added) for a link torque tau [N m]
    and a carriage force [N] held over the step: theta' = omega, q' = q_dot, (omega',
    q_dot', E_loss') = rates(theta, omega, q, q_dot, direction, tau, force), with the
    carriage's direction that of q_dot at the step's start (a self-locking drive's regime is
    held through the step), W_drive' = tau omega, W_force' = force q_dot and E_added' = 0.

    The numbers of `rk4` over the full state, bit for bit, with the stages in local floats:
    one call of rates per stage and no tuple per stage.
    """
    theta, omega, q, q_dot, W_drive, W_force, E_loss, E_added = s
    half, sixth = 0.5 * h, h / 6.0
    a1, b1, l1 = rates(theta, omega, q, q_dot, q_dot, tau, force)
    o2, v2 = omega + half * a1, q_dot + half * b1
    a2, b2, l2 = rates(theta + half * omega, o2, q + half * q_dot, v2, q_dot, tau, force)
    o3, v3 = omega + half * a2, q_dot + half * b2
    a3, b3, l3 = rates(theta + half * o2, o3, q + half * v2, v3, q_dot, tau, force)
    o4, v4 = omega + h * a3, q_dot + h * b3
    a4, b4, l4 = rates(theta + h * o3, o4, q + h * v3, v4, q_dot, tau, force)
    return tuple.__new__(type(s), (
        theta + sixth * (omega + 2.0 * o2 + 2.0 * o3 + o4),
        omega + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
        q + sixth * (q_dot + 2.0 * v2 + 2.0 * v3 + v4),
        q_dot + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4),
        W_drive + sixth * (tau * omega + 2.0 * (tau * o2) + 2.0 * (tau * o3) + tau * o4),
        W_force + sixth * (force * q_dot + 2.0 * (force * v2) + 2.0 * (force * v3)
                           + force * v4),
        E_loss + sixth * (l1 + 2.0 * l2 + 2.0 * l3 + l4),
        E_added + sixth * 0.0))    # E_added' = 0 (-0.0 turns +0.0, as in rk4)


def integrate_link_slider(rates: Callable[[float, float, float, float],
                                          tuple[float, float, float, float]],
                          s: S, tau: float, coupling: float | None, dt: float, n: int,
                          low: float, high: float, constrain: Callable[[Any, Any, S], S],
                          p: Any, u: Any) -> S:
    """Advance a link and a slider along it over dt [s] in n RK4 sub-steps: the state
    (theta, omega, b, v, x_coupled, W_drive, E_loss, E_added) with theta' = omega,
    (omega', b', v', E_loss') = rates(theta, omega, b, v) (b' is v for a slider with mass,
    its creep speed for a massless one), x_coupled' = coupling b' (a body the slider drives:
    None holds it), W_drive' = tau omega for a link torque tau [N m] held over the step and
    E_added' = 0; constrain(p, u, state) (end stops, for the mechanism's parameters p and
    inputs u) after every sub-step that ends with b outside [low, high] [m] (an empty range,
    low > high: after every sub-step).

    The numbers of `integrate_substeps` over the full state with `constrain` after every
    sub-step, bit for bit, wherever constrain leaves a state with b inside alone; the stages
    kept in local floats: one call of rates per stage and no tuple per stage, where the
    tuples, calls and the full-state arithmetic cost more than the slider's own.
    """
    theta, omega, b, v, x_coupled, W_drive, E_loss, E_added = s
    kind = type(s)
    h = dt / n
    half, sixth = 0.5 * h, h / 6.0
    for _ in range(n):
        a1, b1, v1, l1 = rates(theta, omega, b, v)
        o2 = omega + half * a1
        a2, b2, v2, l2 = rates(theta + half * omega, o2, b + half * b1, v + half * v1)
        o3 = omega + half * a2
        a3, b3, v3, l3 = rates(theta + half * o2, o3, b + half * b2, v + half * v2)
        o4 = omega + h * a3
        a4, b4, v4, l4 = rates(theta + h * o3, o4, b + h * b3, v + h * v3)
        # rk4's sums for a held coupled body (rate 0.0) and E_added (rate 0.0): adding
        # sixth times the zero sum is adding 0.0
        if coupling is None:
            x_coupled += 0.0
        else:
            x_coupled += sixth * (coupling * b1 + 2.0 * (coupling * b2)
                                  + 2.0 * (coupling * b3) + coupling * b4)
        W_drive += sixth * (tau * omega + 2.0 * (tau * o2) + 2.0 * (tau * o3) + tau * o4)
        E_loss += sixth * (l1 + 2.0 * l2 + 2.0 * l3 + l4)
        E_added += 0.0
        theta += sixth * (omega + 2.0 * o2 + 2.0 * o3 + o4)
        omega += sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        b += sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
        v += sixth * (v1 + 2.0 * v2 + 2.0 * v3 + v4)
        if not low <= b <= high:
            theta, omega, b, v, x_coupled, W_drive, E_loss, E_added = constrain(
                p, u, tuple.__new__(kind, (theta, omega, b, v, x_coupled, W_drive, E_loss,
                                           E_added)))
    return tuple.__new__(kind, (theta, omega, b, v, x_coupled, W_drive, E_loss, E_added))


def integrate_sine_arm(tau: float, moment: float, spring: float,
                       factor: Callable[[float], float] | None, d: float, J: float,
                       theta: float, omega: float, W_drive: float, E_loss: float, dt: float,
                       n: int) -> tuple[float, float, float, float]:
    """`integrate_arm` for a link of constant inertia J [kg m^2] whose angular acceleration
    is (tau + moment sin(theta) - spring sin(theta) factor(theta) - d omega) / J: a drive
    torque tau [N m], a gravity moment [N m], a spring moment [N m] scaled by factor(theta)
    (None: by exactly 1) and a damper d [N m s/rad], whose loss rate is d omega^2; returns
    (theta, omega, W_drive, E_loss).

    The numbers of `integrate_arm` for those rates, bit for bit, with the stages written
    out: no call per stage, where four calls per sub-step cost more than the link's
    arithmetic.
    """
    sin = math.sin
    h = dt / n
    half, sixth = 0.5 * h, h / 6.0
    f1 = f2 = f3 = f4 = 1.0   # multiplying by 1.0 changes no number
    for _ in range(n):
        t2 = theta + half * omega
        if factor is not None:
            f1, f2 = factor(theta), factor(t2)
        s1 = sin(theta)
        a1 = (tau + moment * s1 - spring * s1 * f1 - d * omega) / J
        o2 = omega + half * a1
        s2 = sin(t2)
        a2 = (tau + moment * s2 - spring * s2 * f2 - d * o2) / J
        o3 = omega + half * a2
        t3 = theta + half * o2
        if factor is not None:
            f3 = factor(t3)
        s3 = sin(t3)
        a3 = (tau + moment * s3 - spring * s3 * f3 - d * o3) / J
        o4 = omega + h * a3
        t4 = theta + h * o3
        if factor is not None:
            f4 = factor(t4)
        s4 = sin(t4)
        a4 = (tau + moment * s4 - spring * s4 * f4 - d * o4) / J
        W_drive += sixth * (tau * omega + 2.0 * (tau * o2) + 2.0 * (tau * o3) + tau * o4)
        E_loss += sixth * (d * omega * omega + 2.0 * (d * o2 * o2) + 2.0 * (d * o3 * o3)
                           + d * o4 * o4)
        theta += sixth * (omega + 2.0 * o2 + 2.0 * o3 + o4)
        omega += sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return theta, omega, W_drive, E_loss


def advance_arm(f: Callable[[float, float], tuple[float, float]], s: S, tau: float, dt: float,
                rate: float, terms: Callable[[S], Sequence[float]], p: Any, payload: float
                ) -> S:
    """A one-link arm's communication step of dt [s] from s, a state (theta, omega, W_drive,
    E_loss, E_added) whose E_added the step leaves alone: `integrate_arm` for the rates f and
    the drive torque tau, its sub-steps from the rate [1/s], raised under `ledger_controlled`
    for the ledger terms(state) of the parameters p and the payload [kg]."""
    theta, omega, W_drive, E_loss, E_added = s

    def run(n: int) -> S:
        return tuple.__new__(type(s), (*integrate_arm(f, theta, omega, W_drive, E_loss, tau,
                                                      dt, n), E_added))

    return ledger_controlled(run, terms, (2,), s, first_substeps(dt, rate), dt, p, (payload,))


def kept_outputs(ledger_terms: Callable) -> Callable:
    """The mechanism's `outputs(p, u, s)` for a `ledger_terms` that evaluates the step's end
    once for the ledger and the outputs and keeps them in `p._kept_outputs[0]` as (state,
    inputs, outputs): the kept outputs when state and inputs are those objects, else a fresh
    evaluation. A closure, so reading the outputs costs one call, as a written-out reader."""
    def outputs(p, u, s):
        kept = p._kept_outputs[0]
        if kept[0] is not s or kept[1] is not u:
            ledger_terms(p, u, s)
            kept = p._kept_outputs[0]
        return kept[2]
    outputs.__doc__ = ("All outputs for the state s and inputs u (those `ledger_terms` "
                       "computed with them at the end of the step, if it did).")
    return outputs
