"""The one-link arms' integrator (`integrate_arm`) against RK4 over the full state.

`integrate_arm` keeps the stages in local floats for speed; it must give the numbers of
`integrate` over the state (theta, omega, W_drive, E_loss) exactly, and so must the
mechanisms that use it, against their own `derivatives`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import pytest

from fmu_src import ciupitu
from fmu_src import rocking_counterweight as rocking
from fmu_src.integration import integrate, integrate_arm


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


@pytest.mark.parametrize("rate", [1.0, 3e3, 4e4], ids=["1 sub-step", "60", "800"])
def test_integrate_arm_is_integrate_over_the_arm_state(rate: float) -> None:
    start = ArmState(2.5, -1.2, 0.3, 0.1)
    expected = integrate(lambda s: (s[1], *pendulum(s[0], s[1])[:1], TAU * s[1],
                                    pendulum(s[0], s[1])[1]), start, 1e-3, rate)
    assert integrate_arm(pendulum, *start, TAU, 1e-3, rate) == tuple(expected)


@pytest.mark.parametrize(("physics", "changes", "inputs"), [
    (ciupitu, {"d_cw": 0.3, "theta0": 1.1, "omega0": 0.4}, (0.2, 0.6)),
    (rocking, {"d_link": 0.05, "theta0": 0.3, "omega0": -0.8}, (-0.4, 0.5)),
], ids=["ciupitu", "rocking"])
def test_arm_advance_is_rk4_over_its_derivatives(physics, changes, inputs) -> None:
    """advance() of the arms (integrate_arm) against integrate() over their derivatives."""
    p = dataclasses.replace(physics.Parameters(), **changes)
    u = physics.Inputs(*inputs)
    fast = full = physics.initial_state(p)
    for dt in (1e-3, 1e-2, 0.1) * 5:
        fast = physics.advance(p, u, fast, dt)
        full = integrate(lambda s: physics.derivatives(p, u, s), full, dt,
                         physics.characteristic_rate(p, u, full))
        assert fast == full and type(fast) is physics.State
