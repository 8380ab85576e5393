"""A joint's drive over a run: `SampledDrive` steps the discrete PID and the sampled motor
together in a fixed-step master and records every step; `DriveTrace` is that record (or one
read back from a system of FMUs), from which the metrics and CSV columns are made."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmu_src.units.controller.pid import DiscretePID
from fmu_src.units.drive.dc_motor import (
    DriveEnergies,
    MotorParameters,
    SampledMotor,
    step_energies,
    stuck_mode_effort,
    transmitted_effort,
)
from fmu_src.units.sequencer.scenario import Joint


class SampledDrive:
    """One joint's discrete PID (`DiscretePID.update`) and sampled motor (`SampledMotor.step`),
    the code the PositionController and DcMotorDrive FMUs run, stepped together at each
    communication step, with a record of each step k: the joint's position and speed at its
    start (and at the end of the last step, `end`), the voltage [V], the armature current at
    its start [A] (and at the end of the last step), its step average [A], the effort [N m or
    N] and whether the drive was on.

    enabled[k]: whether the drive is on over step k. Off, the controller holds its state and
    the motor carries no current; switched on again, the controller starts from the error then
    with its integral reset (no derivative kick, no push left over from before: a drive
    resting while its axis holds by itself has nothing to hold when it comes on).

    inertia: the joint's [kg m^2 or kg], the drive's own included: the effort of a lossy
    transmission inside its stuck mode is then held linearly implicit (`stuck_mode_effort`),
    as the `DcMotorDrive` FMU holds it when given J_joint. None: the effort at the step's
    start speed."""

    def __init__(self, pid: DiscretePID, motor: SampledMotor, reference: Sequence[float],
                 enabled: Sequence[bool] | None = None, inertia: float | None = None) -> None:
        """A drive for a run of len(reference) - 1 steps following reference [rad or m] at
        each communication point; always on unless enabled says otherwise."""
        n_steps = len(reference) - 1
        self.pid, self.motor, self.reference = pid, motor, list(reference)
        lossy = motor.motor.eta < 1.0 or motor.motor.eta_back < 1.0
        self.inertia = inertia if lossy else None
        self.blend = motor.motor.blend_speed
        self.enabled = [True] * n_steps if enabled is None else list(enabled)
        self.on = self.enabled[0] if n_steps else True
        self.position, self.speed = [0.0] * (n_steps + 1), [0.0] * (n_steps + 1)
        self.voltage, self.current, self.effort = [0.0] * n_steps, [0.0] * n_steps, [0.0] * n_steps
        self.start_current = [motor.current] + [0.0] * n_steps

    def step(self, k: int, position: float, speed: float) -> float:
        """Step k from the joint's position and speed at its start; the effort over it."""
        error = self.reference[k] - position
        if self.enabled[k]:
            if not self.on:  # switched on: a bumpless start
                self.pid.reset(error)
                self.on = True
            voltage = self.pid.update(error)
            average, effort = self.motor.step(voltage, speed)
            # inside the stuck mode's blend only: no call per step outside it
            if (self.inertia is not None and -self.blend < speed < self.blend and k > 0
                    and self.enabled[k - 1]):
                dt = self.motor.coefficients.dt
                effort = stuck_mode_effort(self.motor.motor, average, speed, effort,
                                           self.inertia, dt,
                                           (self.speed[k - 1], self.effort[k - 1], dt))
        else:
            self.on = False
            voltage = 0.0
            average, effort = self.motor.step(voltage, speed, enabled=False)
        self.voltage[k], self.current[k], self.effort[k] = voltage, average, effort
        self.start_current[k + 1] = self.motor.current
        self.position[k], self.speed[k] = position, speed
        return effort

    def end(self, position: float, speed: float) -> None:
        """Record the joint's position and speed at the end of the run."""
        self.position[-1], self.speed[-1] = position, speed

    def trace(self, joint: Joint, step_size: float) -> DriveTrace:
        """The drive's record of the run as a `DriveTrace` of steps of step_size [s]."""
        effort = np.array(self.effort)
        return DriveTrace(joint, self.motor.motor, step_size, np.array(self.voltage),
                          np.array(self.current), effort, np.array(self.start_current),
                          np.array(self.position), np.array(self.speed),
                          np.array(self.reference), np.array(self.enabled, dtype=bool),
                          applied=effort)


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
    enabled: np.ndarray | None = None  # whether the drive was on over step k (None: always)
    applied: np.ndarray | None = None  # the effort the drive applied over step k (None: below)

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
        """The effort the drive applied over each step [N m or N]: `applied`, or else
        `transmitted_effort` of the step-average current at the speed it held (it is `effort`
        when the mechanism gets it without delay)."""
        if self.applied is not None:
            return self.applied
        return transmitted_effort(self.motor, self.current, self.speed[:len(self.current)])

    @property
    def on(self) -> np.ndarray:
        """Whether the drive was on over each step (n values)."""
        return (np.ones(len(self.voltage), dtype=bool) if self.enabled is None
                else self.enabled)

    @property
    def travel(self) -> np.ndarray:
        """The joint's travel over each step [rad or m]."""
        return np.diff(self.position)

    def energies(self) -> DriveEnergies:
        """Each step's energies [J], arrays of n (`fmu_src.units.drive.dc_motor.step_energies`)."""
        n = len(self.voltage)
        if np.ndim(self.step_size) == 0:
            return step_energies(self.motor, self.step_size, self.voltage, self.speed[:n],
                                 self.start_current[:n], self.current, self.effort, self.travel,
                                 self.on)
        steps = [step_energies(self.motor, *values) for values in zip(
            self.step_size.tolist(), self.voltage.tolist(), self.speed[:n].tolist(),
            self.start_current[:n].tolist(), self.current.tolist(), self.effort.tolist(),
            self.travel.tolist(), self.on.tolist(), strict=True)]
        return DriveEnergies(*(np.array(values) for values in zip(*steps, strict=True)))
