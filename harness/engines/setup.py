"""A run's set-up, the same in every engine: the mechanism's parameters, each joint's drive
and its PID, and the equilibrium start.

The run starts in equilibrium: the mechanism at rest at the initial positions and each
joint's PID integrator and motor current holding the static effort the mechanism reports for
that joint at t = 0 (the joint's `static_effort` or `static_load` output, e.g. tau_gravity).
That is an initial condition, not a feedforward: during the task each drive gets only its
error."""

from __future__ import annotations

from collections.abc import Mapping

from harness.drive.controller import ControllerDesign, PIDGains, design_pid
from harness.drive.motor import MotorParameters, motors
from harness.scenarios import Joint, Scenario, Variant

Motors = MotorParameters | Mapping[str, MotorParameters] | None


def joint_motors(scenario: Scenario, motor: Motors = None) -> list[MotorParameters]:
    """The motor of each of the scenario's joints (motor as in `harness.drive.motor.motors`:
    None for MOTORS, one MotorParameters replacing the geared motor, or a mapping by name)."""
    drives = motors(motor)
    return [drives[joint.motor] for joint in scenario.joints]


def run_parameters(scenario: Scenario, variant: Variant,
                   drive_motors: list[MotorParameters]) -> dict[str, float | bool]:
    """The mechanism's parameters in a run: the scenario's, the variant's, each joint's
    initial position and the inertia its drive reflects to it."""
    parameters = {**scenario.parameters, **variant.parameters}
    for joint, initial, drive_motor in zip(scenario.joints, scenario.initial_angle,
                                           drive_motors, strict=True):
        parameters |= {joint.start_parameter: initial, joint.drive_inertia: drive_motor.J_drive}
    return parameters


def joint_drive(values: Mapping[str, float], joint: Joint, drive_motor: MotorParameters,
                design: ControllerDesign) -> tuple[PIDGains, float]:
    """For the mechanism at the start of the run (values: its joint's inertia, friction and
    static output by name): the joint's PID, designed for its inertia (plus the drive's) and
    friction, and the motor current [A] that holds the static effort, the run's equilibrium
    start."""
    gains = design_pid(drive_motor, values[joint.inertia] + drive_motor.J_drive,
                       values[joint.friction], design)
    return gains, joint.hold_effort(values[joint.static_output]) / drive_motor.torque_per_amp

