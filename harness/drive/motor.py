"""The DC motor as a python-control system, discretised with python-control.

The model, its energies and its default parameters are defined once, in
`fmu_src.units.drive.dc_motor` (standard library only, so the `DcMotorDrive` FMU runs the same
model); here it becomes a named python-control state-space system and is discretised with
`control.c2d`. A run puts a `JointDrive` on each joint: its model and what the summary reports
of it. LEGACY names the drives of the `legacy` configuration, those a scenario's joint
declares as its `motor` (`fmu_src.units.sequencer.scenario.MOTORS`): one motor type on every
joint, lossless; the harness's default configuration takes each joint's drive from the
catalogue instead (harness.drive.catalogue, harness.drive.sizing). """

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import control as ct
import numpy as np

from fmu_src.units.drive.dc_motor import (
    LEAD_SCREW_MOTOR,
    TRAPEZOIDAL_SCREW_MOTOR,
    MotorParameters,
    SampledMotor,
    StepCoefficients,
    armature_matrices,
    zoh_coefficients,
)
from harness.errors import UserError

__all__ = ["LEGACY", "MOTORS", "JointDrive", "MotorParameters", "SampledMotor", "motor_system",
           "motors", "sampled_motor", "start_currents"]

# joint-side units: N m and rad for "geared", N and m for the screws
MOTORS = {"geared": MotorParameters(), "lead_screw": LEAD_SCREW_MOTOR,
          "trapezoidal_screw": TRAPEZOIDAL_SCREW_MOTOR}


@dataclass(frozen=True)
class JointDrive:
    """The drive a run puts on a joint: its model, and what the summary reports of it: its
    parts, the gearhead's ratio (1 without one), the motor's nominal current [A] and its
    rated power [W]."""

    parameters: MotorParameters
    label: str
    gear_ratio: float
    I_nom: float
    P_nom: float


# the legacy configuration: the maxon RE 30 (3.44 A nominal, 60 W) behind a lossless 111:1
# gearhead, or directly on a joint's lead screw (fmu_src.units.drive.dc_motor)
LEGACY = {
    "geared": JointDrive(MOTORS["geared"], "legacy: maxon RE 30 60 W + lossless 111:1", 111.0,
                         3.44, 60.0),
    "lead_screw": JointDrive(LEAD_SCREW_MOTOR, "legacy: maxon RE 30 60 W on a 40 mm lead "
                             "screw, lossless", 1.0, 3.44, 60.0),
    "trapezoidal_screw": JointDrive(TRAPEZOIDAL_SCREW_MOTOR, "legacy: maxon RE 30 60 W on "
                                    "the Tr 10x2 screw", 1.0, 3.44, 60.0),
}


def motors(motor: MotorParameters | Mapping[str, MotorParameters] | None = None
           ) -> dict[str, MotorParameters]:
    """The drives by name: MOTORS; one MotorParameters replaces the geared motor (the motor of
    one-joint scenarios, e.g. a sweep's `motor.N`); a mapping replaces the named ones."""
    if motor is None:
        return dict(MOTORS)
    if isinstance(motor, MotorParameters):
        return MOTORS | {"geared": motor}
    unknown = sorted(set(motor) - set(MOTORS))
    if unknown:
        raise UserError(f"unknown motor(s) {', '.join(unknown)}; known: {', '.join(MOTORS)}")
    return MOTORS | dict(motor)


def motor_system(motor: MotorParameters) -> ct.StateSpace:
    """Continuous motor model with named signals: inputs (V, omega), outputs (tau_drive, i)."""
    return ct.ss(*armature_matrices(motor), inputs=["V", "omega"], outputs=["tau_drive", "i"],
                 states=["i"], name="motor")


def discretise(motor: MotorParameters, dt: float) -> StepCoefficients:
    """Zero-order-hold step coefficients from control.c2d.

    The armature is augmented with q = integral of i dt and discretised exactly (zoh), so
    that (q[k+1] - q[k]) / dt is the step-average current.
    """
    sys = motor_system(motor)
    A = np.block([[sys.A, np.zeros((1, 1))], [np.ones((1, 1)), np.zeros((1, 1))]])
    B = np.vstack([sys.B, np.zeros((1, 2))])
    discrete = ct.c2d(ct.ss(A, B, np.eye(2), np.zeros((2, 2))), dt, method="zoh")
    (a, _), (avg_a, _) = (discrete.A / np.array([[1.0], [dt]])).tolist()
    (b_v, b_w), (avg_b_v, avg_b_w) = (discrete.B / np.array([[1.0], [dt]])).tolist()
    return StepCoefficients(a, b_v, b_w, avg_a, avg_b_v, avg_b_w, dt)


def sampled_motor(motor: MotorParameters, dt: float, current: float = 0.0) -> SampledMotor:
    """The motor stepped at dt [s], starting with the given armature current [A]."""
    return SampledMotor(motor, discretise(motor, dt), current)


def start_currents(motor: MotorParameters, dt: float | np.ndarray, voltage: np.ndarray,
                   omega: np.ndarray, average: np.ndarray,
                   enabled: np.ndarray | None = None) -> np.ndarray:
    """The armature current [A] at the start of each of n zero-order-hold steps of dt [s]
    (one for all, or one per step) and at the end of the last (n + 1 values), from the
    step-average currents [A] of a drive that held V [V] and omega [rad/s or m/s] over each
    step (e.g. the `DcMotorDrive` FMU's i); enabled: whether the drive was on over each step
    (None: always). A step with the drive off starts with the current the step before ended
    with (0 after one off) and ends with none."""
    steps = np.broadcast_to(dt, np.shape(average))
    on = np.ones(len(average), dtype=bool) if enabled is None else np.asarray(enabled)
    coefficients = [zoh_coefficients(motor, h) for h in
                    ([float(dt)] if np.ndim(dt) == 0 else steps.tolist())]
    pick = (lambda k: coefficients[0]) if np.ndim(dt) == 0 else coefficients.__getitem__
    start, end = np.zeros(len(average) + 1), 0.0
    for k, (i, v, w) in enumerate(zip(average.tolist(), voltage.tolist(), omega.tolist(),
                                      strict=True)):
        if on[k]:
            c = pick(k)
            start[k] = c.start_current(i, v, w)
            end = c.a * start[k] + c.b_v * v + c.b_w * w
        else:
            start[k], end = end, 0.0
    start[-1] = end
    return start
