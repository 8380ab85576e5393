"""The DC motor as a python-control system, discretised with python-control, and a drive's
record of a run.

The model, its energies and its default parameters are defined once, in
`fmu_src.units.drive.dc_motor` (standard library only, so the `DcMotorDrive` FMU runs the same
model); here it becomes a named python-control state-space system and is discretised with
`control.c2d`. MOTORS names the drives a scenario's joint can declare
(`fmu_src.units.sequencer.scenario.MOTORS`). A `DriveTrace` is what one joint's drive held and
did over a run, from which the metrics and CSV columns are made. """

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import control as ct
import numpy as np

from fmu_src.units.drive.dc_motor import (
    LEAD_SCREW_MOTOR,
    TRAPEZOIDAL_SCREW_MOTOR,
    DriveEnergies,
    MotorParameters,
    SampledMotor,
    StepCoefficients,
    armature_matrices,
    step_energies,
    zoh_coefficients,
)
from fmu_src.units.sequencer.scenario import Joint
from harness.errors import UserError

__all__ = ["MOTORS", "DriveTrace", "MotorParameters", "SampledMotor", "motor_system", "motors",
           "sampled_motor", "start_currents"]

# joint-side units: N m and rad for "geared", N and m for the screws
MOTORS = {"geared": MotorParameters(), "lead_screw": LEAD_SCREW_MOTOR,
          "trapezoidal_screw": TRAPEZOIDAL_SCREW_MOTOR}


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
    return StepCoefficients(a, b_v, b_w, avg_a, avg_b_v, avg_b_w)


def sampled_motor(motor: MotorParameters, dt: float, current: float = 0.0) -> SampledMotor:
    """The motor stepped at dt [s], starting with the given armature current [A]."""
    return SampledMotor(motor, discretise(motor, dt), current)


def start_currents(motor: MotorParameters, dt: float | np.ndarray, voltage: np.ndarray,
                   omega: np.ndarray, average: np.ndarray) -> np.ndarray:
    """The armature current [A] at the start of each of n zero-order-hold steps of dt [s]
    (one for all, or one per step) and at the end of the last (n + 1 values), from the
    step-average currents [A] of a drive that held V [V] and omega [rad/s or m/s] over each
    step (e.g. the `DcMotorDrive` FMU's i)."""
    if np.ndim(dt) == 0:
        coefficients = zoh_coefficients(motor, dt)
        start = coefficients.start_current(average, voltage, omega)
        last = SampledMotor(motor, coefficients, float(start[-1]))
    else:
        start = np.array([zoh_coefficients(motor, h).start_current(i, v, w) for h, i, v, w
                          in zip(dt.tolist(), average.tolist(), voltage.tolist(),
                                 omega.tolist(), strict=True)])
        last = SampledMotor(motor, zoh_coefficients(motor, float(dt[-1])), float(start[-1]))
    last.step(float(voltage[-1]), float(omega[-1]))
    return np.append(start, last.current)


@dataclass(frozen=True)
class DriveTrace:
    """One joint's drive over a run of n communication steps of step_size [s] (one for all,
    or n of them: variable steps): per step k < n what it held and carried (n values), and at
    each communication point t_k, k = 0..n, the armature current and the joint (n + 1
    values). Efforts in N m and positions in rad for a revolute joint, N and m for a
    prismatic one."""

    joint: Joint
    motor: MotorParameters
    step_size: float | np.ndarray
    voltage: np.ndarray        # held over step k [V]
    current: np.ndarray        # armature current, average over step k [A]
    effort: np.ndarray         # effort the mechanism received over step k
    start_current: np.ndarray  # armature current at t_k [A]; the last, at the end of the run
    position: np.ndarray       # joint position at t_k
    speed: np.ndarray          # joint speed at t_k, which the drive holds over step k
    reference: np.ndarray      # position reference at t_k

    @property
    def final_current(self) -> float:
        """The armature current at the end of the run [A]."""
        return float(self.start_current[-1])

    @property
    def steps(self) -> np.ndarray:
        """The length of each step [s] (n values)."""
        return np.broadcast_to(self.step_size, (len(self.voltage),))

    @property
    def times(self) -> np.ndarray:
        """The communication points t_k [s], k = 0..n: k step_size, or the steps summed."""
        if np.ndim(self.step_size) == 0:
            return np.arange(len(self.position)) * self.step_size
        return np.concatenate([[0.0], np.cumsum(self.step_size)])

    @property
    def shaft_effort(self) -> np.ndarray:
        """The effort the drive applies over each step, eta N K_t i (the step average; it is
        `effort` when the mechanism gets it without delay) [N m or N]."""
        return self.motor.torque_per_amp * self.current

    @property
    def travel(self) -> np.ndarray:
        """The joint's travel over each step [rad or m]."""
        return np.diff(self.position)

    def energies(self) -> DriveEnergies:
        """Each step's energies [J], arrays of n (`fmu_src.units.drive.dc_motor.step_energies`)."""
        n = len(self.voltage)
        if np.ndim(self.step_size) == 0:
            return step_energies(self.motor, self.step_size, self.voltage, self.speed[:n],
                                 self.start_current[:n], self.current, self.effort, self.travel)
        steps = [step_energies(self.motor, *values) for values in zip(
            self.step_size.tolist(), self.voltage.tolist(), self.speed[:n].tolist(),
            self.start_current[:n].tolist(), self.current.tolist(), self.effort.tolist(),
            self.travel.tolist(), strict=True)]
        return DriveEnergies(*(np.array(values) for values in zip(*steps, strict=True)))
