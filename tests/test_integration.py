"""The integration kernels (`integrate_arm`, `integrate_sine_arm`, `integrate_link_slider`,
`rk4_link_carriage_step`) against RK4 over the full state, and the ledger's control of the
sub-steps (`ledger_controlled`).

The kernels keep the stages in local floats for speed; each must give the numbers of `rk4`
or `integrate_substeps` over its state exactly, and so must the mechanisms that use them,
against their own `derivatives` under the same ledger control.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace
from typing import NamedTuple

import pytest
from conftest import controlled_reference

from fmu_src.integration import (
    MAX_SUBSTEPS,
    SubstepBoundError,
    integrate_arm,
    integrate_link_slider,
    integrate_sine_arm,
    integrate_substeps,
    ledger_controlled,
    rk4,
    rk4_link_carriage_step,
)
from fmu_src.mechanisms.ciupitu import physics as ciupitu
from fmu_src.mechanisms.rocking_counterweight import physics as rocking


class ArmState(NamedTuple):
    theta: float
    omega: float
    W_drive: float
    E_loss: float


TAU = 0.7  # N m


def pendulum(theta: float, omega: float) -> tuple[float, float]:
    """A damped pendulum whose friction grows with the angle: acceleration and loss power."""
    damping = 0.05 + 0.02 * math.cos(theta) ** 2
    return TAU - 9.81 * math.sin(theta) - damping * omega, damping * omega * omega


def pendulum_rates(s: ArmState) -> tuple[float, ...]:
    """The pendulum's full state derivative (theta, omega, W_drive, E_loss)."""
    omega_dot, loss = pendulum(s[0], s[1])
    return s[1], omega_dot, TAU * s[1], loss


def pendulum_ledger(s: ArmState) -> tuple[float, ...]:
    """The pendulum's ledger terms: its energy (J = 1), E_loss and -W_drive [J]."""
    return -9.81 * math.cos(s[0]), 0.5 * s[1] ** 2, s[3], -s[2]


@pytest.mark.parametrize("n", [1, 60, 800])
def test_integrate_arm_is_integrate_over_the_arm_state(n: int) -> None:
    start = ArmState(2.5, -1.2, 0.3, 0.1)
    expected = integrate_substeps(pendulum_rates, start, 1e-3, n)
    assert integrate_arm(pendulum, *start, TAU, 1e-3, n) == tuple(expected)


@pytest.mark.parametrize("n", [1, 60])
@pytest.mark.parametrize("real_spring", [False, True])
def test_integrate_sine_arm_is_integrate_arm(n: int, real_spring: bool) -> None:
    """The written-out sine arm against `integrate_arm` over the same rates, bit for bit."""
    moment, spring, d, J = 4.2, 3.9, 0.05, 0.8

    def factor(theta: float) -> float:
        return 1.0 - 0.02 / (0.3 + 0.1 * math.cos(theta))

    def rates(theta: float, omega: float) -> tuple[float, float]:
        sin_t = math.sin(theta)
        return ((TAU + moment * sin_t - spring * sin_t * (factor(theta) if real_spring else 1.0)
                 - d * omega) / J, d * omega * omega)

    start = (2.5, -1.2, 0.3, 0.1)
    expected = integrate_arm(rates, *start, TAU, 1e-3, n)
    assert integrate_sine_arm(TAU, moment, spring, factor if real_spring else None, d, J,
                              *start, 1e-3, n) == expected


class SliderState(NamedTuple):
    theta: float
    omega: float
    b: float
    v: float
    x_coupled: float
    W_drive: float
    E_loss: float
    E_added: float


B_STOP = 0.301  # m, the slider's outer stop in the tests below


def slider_rates(theta: float, omega: float, b: float, v: float
                 ) -> tuple[float, float, float, float]:
    """A link with a sprung slider along it: (omega', b', v', E_loss')."""
    J = 0.5 + 2.0 * b * b
    omega_dot = (TAU + 3.0 * math.sin(theta) - 0.1 * omega - 4.0 * b * v * omega) / J
    v_dot = b * omega * omega - 9.81 * math.cos(theta) - 40.0 * (b - 0.2) - 0.3 * v
    return omega_dot, v, v_dot, 0.1 * omega * omega + 0.3 * v * v


STOPS: list[float] = []   # b of every state stop_slider clamps


def stop_slider(p: object, u: object, s: SliderState) -> SliderState:
    """The outer end stop: b clamped, an outward speed stopped (the test's constraint)."""
    if s.b <= B_STOP:
        return s
    STOPS.append(s.b)
    return s._replace(b=B_STOP, v=min(s.v, 0.0))


@pytest.mark.parametrize("coupling", [None, 2.5])
@pytest.mark.parametrize("n", [1, 40])
def test_integrate_link_slider_is_integrate_over_the_state(coupling: float | None,
                                                           n: int) -> None:
    """Within the stop and onto it, the slider kernel equals `integrate_substeps` over the
    full state with the stop after every sub-step, bit for bit."""
    def full_rates(s: SliderState) -> tuple[float, ...]:
        omega_dot, b_dot, v_dot, loss = slider_rates(*s[:4])
        return (s[1], omega_dot, b_dot, v_dot, 0.0 if coupling is None else coupling * b_dot,
                TAU * s[1], loss, 0.0)

    for start in (SliderState(0.4, 0.3, 0.25, 0.1, 0.01, 0.2, 0.1, -0.0),
                  SliderState(0.4, 0.3, 0.29, 1.5, 0.01, 0.2, 0.1, 0.0)):   # reaches the stop
        STOPS.clear()
        expected = integrate_substeps(full_rates, start, 0.05, n,
                                      lambda s: stop_slider(None, None, s))
        got = integrate_link_slider(slider_rates, start, TAU, coupling, 0.05, n, -math.inf,
                                    B_STOP, stop_slider, None, None)
        assert type(got) is SliderState
        assert [(x, math.copysign(1.0, x)) for x in got] == [
            (x, math.copysign(1.0, x)) for x in expected]
    assert len(STOPS) >= 2   # the second start reaches the stop (in both integrations)


def test_rk4_link_carriage_step_is_rk4() -> None:
    """The link-and-carriage step against `rk4` over the full state, bit for bit, with the
    carriage's direction held at that of the step's start."""
    force = -3.0

    def rates(theta: float, omega: float, q: float, q_dot: float, direction: float,
              tau: float, F: float) -> tuple[float, float, float]:
        friction = 0.4 if direction > 0.0 else -0.4
        return ((tau + 2.0 * math.sin(theta) - 0.1 * omega) / 0.7,
                (F - 30.0 * q - friction) / 0.2, 0.1 * omega * omega + friction * q_dot)

    start = SliderState(0.4, 0.3, 0.02, 0.05, 0.2, 0.1, 0.3, -0.0)

    def full_rates(s: list[float]) -> tuple[float, ...]:
        omega_dot, q_ddot, loss = rates(*s[:4], start.v, TAU, force)
        return s[1], omega_dot, s[3], q_ddot, TAU * s[1], force * s[3], loss, 0.0

    expected = rk4(full_rates, start, 0.05)
    got = rk4_link_carriage_step(rates, TAU, force, start, 0.05)
    assert [(x, math.copysign(1.0, x)) for x in got] == [
        (x, math.copysign(1.0, x)) for x in expected]


def pendulum_step(start: ArmState, dt: float, accuracy: float, n: int = 1) -> ArmState:
    """The pendulum's step of dt [s] under ledger control from n sub-steps."""
    return ledger_controlled(lambda m: integrate_substeps(pendulum_rates, start, dt, m),
                             pendulum_ledger, (2,), start, n, dt,
                             SimpleNamespace(ledger_accuracy=accuracy))


@pytest.mark.parametrize("accuracy", [1e-6, 1e-9, 1e-12])
def test_ledger_control_meets_the_accuracy_over_a_long_step(accuracy: float) -> None:
    """One sub-step over 0.1 s leaves a ledger error of ~1e-6 J (checked); the control raises
    the sub-steps until the error is within accuracy times the work, with the fewest
    sub-steps that do so within a factor of about 2."""
    start, dt = ArmState(2.5, -1.2, 0.0, 0.0), 0.1
    one = integrate_substeps(pendulum_rates, start, dt, 1)
    assert abs(sum(pendulum_ledger(one)) - sum(pendulum_ledger(start))) > 1e-6
    end = pendulum_step(start, dt, accuracy)
    work = abs(end.W_drive)
    error = abs(sum(pendulum_ledger(end)) - sum(pendulum_ledger(start)))
    assert error <= accuracy * work + 1e-13
    n = next(m for m in range(1, MAX_SUBSTEPS) if integrate_substeps(
        pendulum_rates, start, dt, m) == end)
    half = integrate_substeps(pendulum_rates, start, dt, n // 2)
    assert abs(sum(pendulum_ledger(half)) - sum(pendulum_ledger(start))) > accuracy * work


def test_ledger_control_keeps_a_step_that_meets_it() -> None:
    start = ArmState(2.5, -1.2, 0.0, 0.0)
    assert pendulum_step(start, 1e-3, 1e-9, 3) == integrate_substeps(
        pendulum_rates, start, 1e-3, 3)


def test_ledger_control_refuses_a_step_beyond_the_substep_bound() -> None:
    """A ledger error that does not fall with the sub-steps (here 1 J booked by every step)
    raises SubstepBoundError once MAX_SUBSTEPS would be exceeded."""
    start = ArmState(0.0, 0.0, 0.0, 0.0)
    calls = []

    def run(n: int) -> ArmState:
        calls.append(n)
        return start._replace(E_loss=1.0)

    with pytest.raises(SubstepBoundError, match="ledger_accuracy = 1e-09"):
        ledger_controlled(run, pendulum_ledger, (2,), start, 1, 1e-3,
                          SimpleNamespace(ledger_accuracy=1e-9))
    assert calls[-1] <= MAX_SUBSTEPS and all(b >= 2 * a for a, b in zip(calls, calls[1:]))


@pytest.mark.parametrize(("physics", "changes", "inputs"), [
    (ciupitu, {"d_cw": 0.3, "theta0": 1.1, "omega0": 0.4}, (0.2, 0.6)),
    (rocking, {"d_link": 0.05, "theta0": 0.3, "omega0": -0.8}, (-0.4, 0.5)),
    (ciupitu, {"theta0": 1.1, "omega0": 3.0, "ledger_accuracy": 1e-14}, (2.0, 0.6)),
    (rocking, {"theta0": 0.3, "omega0": -3.0, "ledger_accuracy": 1e-14}, (-2.0, 0.5)),
], ids=["ciupitu", "rocking", "ciupitu refined", "rocking refined"])
def test_arm_advance_is_rk4_over_its_derivatives(physics, changes, inputs) -> None:
    """advance() of the arms (integrate_arm) against RK4 over their derivatives under the
    same ledger control (the refined cases take more sub-steps than the rate rule)."""
    p = dataclasses.replace(physics.Parameters(), **changes)
    u = physics.Inputs(*inputs)
    fast = full = physics.initial_state(p)
    for dt in (1e-3, 1e-2, 0.1) * 5:
        fast = physics.advance(p, u, fast, dt)
        full = controlled_reference(physics, p, u, full, dt, (2,))
        assert fast == full and type(fast) is physics.State
