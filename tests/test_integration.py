"""The ledger's control of the RK4 sub-steps (`integration.ledger_controlled`) on a damped,
driven pendulum whose energy ledger is known in closed form."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import NamedTuple

import pytest

from fmu_src.integration import (
    MAX_SUBSTEPS,
    SubstepBoundError,
    integrate_substeps,
    ledger_controlled,
)


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
