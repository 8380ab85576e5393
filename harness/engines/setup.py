"""A run's set-up, the same in every engine: the mechanism's parameters, each joint's drive
and its PID, and the equilibrium start.

The run starts in equilibrium: the mechanism at rest at the initial positions and each
joint's PID integrator and motor current holding the static effort the mechanism reports for
that joint at t = 0 (the joint's `static_effort` or `static_load` output, e.g. tau_gravity).
That is an initial condition, not a feedforward: during the task each drive gets only its
error."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from harness.drive.controller import ControllerDesign, PIDGains, design_pid
from harness.drive.motor import LEGACY, JointDrive, MotorParameters, motors
from harness.errors import UserError
from harness.scenarios import Joint, Scenario, Variant

Motors = MotorParameters | Mapping[str, MotorParameters] | None
Drives = Mapping[str, JointDrive] | None


def joint_drives(scenario: Scenario, motor: Motors = None, drives: Drives = None
                 ) -> list[JointDrive]:
    """The drive of each of the scenario's joints: drives by joint name, or the legacy drive
    each joint names (`harness.drive.motor.LEGACY`) with motor's parameters (as in
    `harness.drive.motor.motors`: None, one MotorParameters replacing the geared motor, or a
    mapping by name)."""
    if drives is not None:
        missing = [joint.name for joint in scenario.joints if joint.name not in drives]
        if missing:
            raise UserError(f"scenario {scenario.name}: no drive for joint(s) "
                            f"{', '.join(missing)}")
        return [drives[joint.name] for joint in scenario.joints]
    legacy = motors(motor)
    return [replace(LEGACY[joint.motor], parameters=legacy[joint.motor])
            for joint in scenario.joints]


def joint_motors(scenario: Scenario, motor: Motors = None, drives: Drives = None
                 ) -> list[MotorParameters]:
    """The model of each of the scenario's joints' drives (`joint_drives`)."""
    return [drive.parameters for drive in joint_drives(scenario, motor, drives)]


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
    gains = design_pid(drive_motor, joint_inertia(values, joint, drive_motor),
                       values[joint.friction], design)
    return gains, hold_current(drive_motor, joint, values[joint.static_output])


def joint_inertia(values: Mapping[str, float], joint: Joint, drive_motor: MotorParameters
                  ) -> float:
    """The joint's inertia with its drive's reflected rotor [kg m^2 or kg], values: the
    mechanism's outputs by name."""
    return values[joint.inertia] + drive_motor.J_drive


def hold_current(drive_motor: MotorParameters, joint: Joint, static_output: float) -> float:
    """The motor current [A] that holds the joint's static output at standstill."""
    return joint.hold_effort(static_output) / drive_motor.standstill_torque_per_amp


def enabled_steps(scenario: Scenario, joint: int, times: np.ndarray) -> list[bool]:
    """Whether the joint's drive is on over each step from times[k] (len(times) - 1 values):
    that of the phase holding the step's start (`Scenario.drive_enabled`)."""
    per_phase = np.array(scenario.drive_enabled(joint), dtype=bool)
    phase = np.clip(scenario.phase_indices(times[:-1]), 0, len(per_phase) - 1)
    return per_phase[phase].tolist()
