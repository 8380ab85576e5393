"""A joint's drive in one run, planned once for every engine: `DrivePlan` holds its parts and
model, its PID designed for the joint, its equilibrium start, its reference and when it is
on; `DrivePlan.sampled` makes the form a fixed-step master steps, `DrivePlan.fmu_parameters`
the parameters of the PositionController and DcMotorDrive FMUs that run it in a system of
FMUs, and `harness.drive.continuous` the form a continuous solver integrates.

The run starts in equilibrium: the joint at rest and its PID integrator and motor current
holding the static effort the mechanism reports for the joint at t = 0 (its `static_effort`
or `static_load` output, e.g. tau_gravity). That is an initial condition, not a
feedforward: during the task the drive gets only its error. A drive off from the start holds
nothing.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from fmu_src.units.controller.pid import PIDGains
from fmu_src.units.drive.dc_motor import MotorParameters, armature_voltage
from harness.drive import stability
from harness.drive.controller import ControllerDesign, design_pid, discrete_pid
from harness.drive.motor import JointDrive, sampled_motor
from harness.drive.trace import SampledDrive
from harness.errors import UserError
from harness.scenarios import Joint


@dataclass(frozen=True)
class JointStart:
    """What the mechanism reports of a joint at t = 0: its inertia [kg m^2 or kg] and
    viscous friction [N m s/rad or N s/m] (without the drive's) and its static output [N m or
    N] (`Joint.static_output`)."""

    inertia: float
    friction: float
    static_output: float


@dataclass(frozen=True, eq=False)
class DrivePlan:
    """One joint's drive over a run of len(enabled) steps of step_size [s]: the drive
    (its parts and model), the PID gains, the armature current at t = 0 [A], the joint's
    inertia with the drive's reflected rotor [kg m^2 or kg] and viscous friction [N m s/rad
    or N s/m], its position at t = 0 and the
    position reference at every communication point [rad or m], whether the drive is on over
    each step, and over each phase of the scenario."""

    joint: Joint
    drive: JointDrive
    gains: PIDGains
    hold_current: float
    inertia: float
    friction: float
    position0: float
    reference: np.ndarray
    enabled: np.ndarray
    phase_enabled: tuple[bool, ...]
    step_size: float

    @property
    def motor(self) -> MotorParameters:
        """The drive's model."""
        return self.drive.parameters

    @property
    def integral0(self) -> float:
        """The PID integral [V] at t = 0: the voltage that holds the start current."""
        return armature_voltage(self.motor, self.hold_current, 0.0)

    def sampled(self) -> SampledDrive:
        """The drive as a fixed-step master steps it (`SampledDrive`), starting in
        equilibrium with the joint at its reference."""
        pid = discrete_pid(self.gains, self.step_size, self.motor.V_supply)
        pid.reset(self.reference[0] - self.position0, integral=self.integral0)
        return SampledDrive(pid, sampled_motor(self.motor, self.step_size, self.hold_current),
                            self.reference.tolist(), self.enabled.tolist(), self.inertia)

    def fmu_parameters(self) -> tuple[dict[str, float], dict[str, float]]:
        """The parameters of the PositionController and of the DcMotorDrive FMU that run the
        drive in a system of FMUs, the same gains, model and start."""
        controller = {**self.gains._asdict(), "V_supply": self.motor.V_supply,
                      "integral0": self.integral0}
        return controller, {**asdict(self.motor), "i0": self.hold_current}


def design_drive(joint: Joint, drive: JointDrive, start: JointStart,
                 design: ControllerDesign, step_size: float) -> tuple[PIDGains, float]:
    """The joint's PID, designed for its inertia (with the drive's) and friction, and that
    inertia [kg m^2 or kg]; UserError when the sampled loop does not hold at step_size [s]
    (`harness.drive.stability`), naming the largest step it holds."""
    motor = drive.parameters
    inertia = start.inertia + motor.J_drive
    gains = design_pid(motor, inertia, start.friction, design)
    radius = stability.spectral_radius(motor, gains, inertia, start.friction, step_size)
    if not radius < 1.0:
        largest = stability.largest_stable_step(motor, gains, inertia, start.friction,
                                                step_size)
        raise UserError(f"step = {step_size:g} s is too long for joint {joint.name}'s drive "
                        f"({drive.label}): its sampled loop diverges (spectral radius "
                        f"{radius:.3g}); it holds up to {largest:.3g} s")
    return gains, inertia


def plan_drive(joint: Joint, drive: JointDrive, start: JointStart, design: ControllerDesign,
               position0: float, reference: np.ndarray, enabled: np.ndarray,
               phase_enabled: tuple[bool, ...], step_size: float) -> DrivePlan:
    """A joint's DrivePlan: its PID (`design_drive`) and the current that holds the static
    output at standstill (none when the drive is off from the start)."""
    motor = drive.parameters
    gains, inertia = design_drive(joint, drive, start, design, step_size)
    hold = (joint.hold_effort(start.static_output) / motor.standstill_torque_per_amp
            if enabled[0] else 0.0)
    return DrivePlan(joint, drive, gains, hold, inertia, start.friction, position0, reference,
                     enabled, phase_enabled, step_size)
