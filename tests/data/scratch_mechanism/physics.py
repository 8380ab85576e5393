"""A damped pendulum: the scratch mechanism of tests/test_registry.py, added to a copy of
fmu_src through its own two files only (docs/adding_a_mechanism.md). Standard library only.

theta is the angle from the downward vertical, counter-clockwise positive:
J theta'' = tau_drive - m g l sin(theta) - d_link omega with J = m l^2 + J_drive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from fmu_src.integration import integrate
from fmu_src.mechanism import (
    input_variables,
    no_event_indicators,
    no_event_update,
    no_input_events,
    no_mode,
    output_variables,
    state_variables,
    variable,
)
from fmu_src.parameters import check_ranges, parameter


@dataclass(frozen=True)
class Parameters:
    """A point mass on a massless rod."""

    m: float = parameter(1.0, "kg", "Bob mass", min=0.0, min_exclusive=True)
    l: float = parameter(0.5, "m", "Rod length", min=0.0, min_exclusive=True)  # noqa: E741
    d_link: float = parameter(0.01, "N.m.s/rad", "Viscous friction at the pivot", min=0.0)
    g: float = parameter(9.81, "m/s2", "Gravitational acceleration", min=0.0)
    theta0: float = parameter(0.0, "rad", "Initial angle from the downward vertical")
    omega0: float = parameter(0.0, "rad/s", "Initial angular velocity")
    J_drive: float = parameter(0.0, "kg.m2", "Drive inertia reflected to the pivot", min=0.0)

    @property
    def J_link(self) -> float:
        """Moment of inertia of the bob about the pivot, m l^2 [kg m^2]."""
        return self.m * self.l * self.l


def validate(params: Parameters) -> None:
    """ValueError naming the first parameter outside its range."""
    check_ranges(params)


class Inputs(NamedTuple):
    """Inputs held over a communication step."""

    tau_drive: float = 0.0  # N m, drive torque about the pivot


INPUT_VARIABLES = input_variables(
    Inputs, tau_drive=variable("N.m", "Drive torque about the pivot"))


EVENT_INPUTS: tuple[str, ...] = ()  # the drive torque is no event


class State(NamedTuple):
    """Angle [rad], speed [rad/s] and the cumulative energies of the ledger [J]."""

    theta: float
    omega: float
    W_drive: float = 0.0
    E_loss: float = 0.0


def initial_state(p: Parameters) -> State:
    """State at the start time."""
    return State(p.theta0, p.omega0)


def inertia(p: Parameters) -> float:
    """Moment of inertia about the pivot with the drive's [kg m^2]."""
    return p.J_link + p.J_drive


def tau_gravity(p: Parameters, theta: float) -> float:
    """Gravity torque about the pivot along theta [N m]."""
    return -p.m * p.g * p.l * math.sin(theta)


def derivatives(p: Parameters, u: Inputs, s: State, rates: Inputs | None = None,
                mode: tuple[int, ...] | None = None) -> State:
    """ds/dt for the inputs held (no input ramps a mass: rates is not used; one regime:
    mode is not used). s is read by position: the integrator passes its intermediate states
    as plain lists."""
    theta, omega = s[0], s[1]
    torque = u.tau_drive + tau_gravity(p, theta) - p.d_link * omega
    return State(omega, torque / inertia(p), u.tau_drive * omega, p.d_link * omega * omega)


def characteristic_rate(p: Parameters, u: Inputs, s: State) -> float:
    """Fastest rate of the local dynamics [1/s]."""
    J = inertia(p)
    return max(math.sqrt(p.m * p.g * p.l / J), p.d_link / J, abs(s.omega))


def advance(p: Parameters, u: Inputs, s: State, dt: float) -> State:
    """The state after a communication step dt [s] (RK4 sub-steps)."""
    return integrate(lambda state: derivatives(p, u, state), s, dt, characteristic_rate(p, u, s))


switch_inputs = no_input_events  # EVENT_INPUTS is empty


class Outputs(NamedTuple):
    """Observable quantities (SI units)."""

    theta: float
    omega: float
    tau_gravity: float
    E_p: float
    E_kin: float
    W_drive: float
    E_loss: float


OUTPUT_VARIABLES = output_variables(
    Outputs, Inputs,
    theta=variable("rad", "Angle from the downward vertical"),
    omega=variable("rad/s", "Angular velocity"),
    tau_gravity=variable("N.m", "Gravity torque about the pivot along theta"),
    E_p=variable("J", "Gravitational potential energy (0 at the pivot's height)"),
    E_kin=variable("J", "Kinetic energy of the bob and the drive rotor"),
    W_drive=variable("J", "Cumulative work of tau_drive"),
    E_loss=variable("J", "Cumulative energy dissipated by the pivot's friction"),
)


def outputs(p: Parameters, u: Inputs, s: State) -> Outputs:
    """Outputs at the state s."""
    return Outputs(s.theta, s.omega, tau_gravity(p, s.theta), -p.m * p.g * p.l * math.cos(s.theta),
                   0.5 * inertia(p) * s.omega * s.omega, s.W_drive, s.E_loss)


# Model Exchange: one smooth regime, no state events; every state is an output
STATE_VARIABLES = state_variables(State, Outputs)
EVENT_INDICATORS = ()
mode, event_indicators, event_update = no_mode, no_event_indicators, no_event_update


def state_nominals(p: Parameters) -> tuple[float, ...]:
    """1 rad, 1 rad/s and 1 J."""
    return (1.0, 1.0, 1.0, 1.0)
