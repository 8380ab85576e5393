"""FMI 2.0 Co-Simulation slave of the geared DC motor drive (docs/drive_and_controller.md).

A thin layer over `fmu_src.units.drive.dc_motor`, the model the harness uses: the voltage V,
limited to +-V_supply, and the joint speed omega are held over each communication step, and the
armature current advances by the exact zero-order hold of that step (`zoh_coefficients`,
recomputed when the step size changes), exactly as the harness's `SampledMotor` does.

Outputs after fmi2DoStep(t, h) belong to the step just taken: i is the average armature
current over [t, t + h], tau_drive the effort the drive applies over that step (N K_t i through
the lossy transmission: times eta where the motor drives the joint, over eta_back where the
joint drives the motor, `transmitted_effort`) and P_elec = V i its average electrical power
(so P_elec h is the step's exact electrical energy). Given the joint's inertia J_joint, a
lossy transmission's effort inside its stuck mode is held linearly implicit, as the harness's
master holds it (`stuck_mode_effort`: the joint's other efforts estimated from the step
before; docs/drives.md). With `enable` false over a step the
drive is switched off: no current, no effort. A master that steps this FMU before the
mechanism over the same interval and passes tau_drive on (Gauss-Seidel) reproduces the
harness's co-simulation (with J_joint set, where the transmission is lossy).

Energies from the start, summed over the steps as the harness's metrics sum them (both take
each step's energies from `fmu_src.units.drive.dc_motor.step_energies`): E_in = integral of V i dt
(regeneration credited); E_drawn, the energy from a supply that cannot take energy back,
max(P_elec, 0) h per step (exact while the current keeps its sign within a step); E_copper =
R_a integral of i^2 dt, exact (and the armature's magnetic energy when the drive is switched
off); E_gear, the transmission's loss. The drive's own account closes: E_in = E_copper + E_gear
+ the work it passes on at the speed it holds + the armature's magnetic energy's change.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fmu_src.fmi.slave import ModelSlave
from fmu_src.fmi.vocabulary import DefaultExperiment
from fmu_src.mechanism import ANGULAR, ELECTROMAGNETIC, DocumentedRun, Port, Registration, Run
from fmu_src.parameters import parameter
from fmu_src.units.drive.dc_motor import (
    MotorParameters,
    SampledMotor,
    step_energies,
    stuck_mode_effort,
    transmitted_effort,
    zoh_coefficients,
)

STEP_SIZE = 1e-3  # default communication step [s], the harness's


@dataclass(frozen=True)
class DriveParameters(MotorParameters):
    """The motor's parameters and its armature current at the start."""

    i0: float = parameter(0.0, "A", "Armature current at the start time (e.g. the current "
                          "holding a static load: -tau_gravity / (eta N K_t))")
    J_joint: float = parameter(0.0, "kg.m2", "Inertia of the joint the drive turns, J_drive "
                               "included (kg for a prismatic joint); above 0, the effort of a "
                               "lossy transmission in its stuck mode is held linearly implicit; "
                               "0: at the step's start speed", min=0.0)


class DcMotorDrive(ModelSlave):
    """DC motor with gearbox: armature L_a di/dt = V - R_a i - K_e N omega, joint-side effort
    tau_drive = N K_t i through the lossy transmission."""

    parameters_type = DriveParameters
    hidden_state = ("armature", "previous")
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.5, step_size=STEP_SIZE)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Geared DC motor drive (armature R-L circuit with back-EMF, "
                            "gearbox), stepped by the exact zero-order hold of each "
                            "communication step")
        self.add_calculated_parameter("J_drive", "kg.m2", "Rotor inertia reflected to the "
                                      "joint, J_rotor N^2: set it as the mechanism's J_drive")
        self.add_input("V", 0.0, "V", "Armature voltage command; saturated to [-V_supply, "
                       "V_supply] before it reaches the armature")
        self.add_input("omega", 0.0, "rad/s", "Joint speed (back-EMF K_t N omega)")
        self.add_input("enable", True, None, "The drive is on; off (false), its amplifier "
                       "is open: no current, no effort")
        for name, unit, description in OUTPUTS:
            # outputs of the last step, so of no input now; P_elec = V i0 at the start
            self.add_output(name, unit, description,
                            initial_depends_on=INITIAL_DEPENDENCIES.get(name, ()))
        self.motor: SampledMotor | None = None
        self.step_size = 0.0  # the step size the motor's coefficients are for [s]
        # (omega, tau_drive, step size, whether the drive was on) of the last step: the stuck
        # mode's estimate of the joint's other efforts; a fixed shape, as an FMU state's
        # hidden part
        self.previous: tuple[float, float, float, bool] = (0.0, 0.0, STEP_SIZE, False)

    def voltage(self) -> float:
        """The input voltage limited to +-V_supply [V]."""
        return min(max(float(self.V), -self.params.V_supply), self.params.V_supply)

    def initialise(self, params: DriveParameters) -> None:
        self.J_drive = params.J_drive
        self.step_size = STEP_SIZE
        self.motor = SampledMotor(params, zoh_coefficients(params, self.step_size), params.i0)
        self.i = params.i0
        self.tau_drive = transmitted_effort(params, params.i0, float(self.omega))
        self.P_elec = self.voltage() * params.i0
        self.E_in = self.E_drawn = self.E_copper = self.E_gear = 0.0
        self.previous = (0.0, 0.0, STEP_SIZE, False)

    def step(self, dt: float) -> None:
        p, motor = self.params, self.motor
        if dt != self.step_size:
            motor.coefficients = zoh_coefficients(p, dt)
            self.step_size = dt
        enabled, omega, i_start = bool(self.enable), float(self.omega), motor.current
        voltage = self.voltage() if enabled else 0.0
        self.i, self.tau_drive = motor.step(voltage, omega, enabled)
        if p.J_joint > 0.0 and enabled:
            omega_before, tau_before, dt_before, was_on = self.previous
            self.tau_drive = stuck_mode_effort(
                p, self.i, omega, self.tau_drive, p.J_joint, dt,
                (omega_before, tau_before, dt_before) if was_on else None)
        self.previous = (omega, self.tau_drive, dt, enabled)
        self.P_elec = voltage * self.i
        # the drive does not see the joint's travel: its mechanical work is not an output
        energies = step_energies(p, dt, voltage, omega, i_start, self.i, self.tau_drive, 0.0,
                                 enabled)
        self.E_in += energies.E_in
        self.E_drawn += energies.E_drawn
        self.E_copper += energies.E_copper
        self.E_gear += energies.E_gear

    @property
    def armature(self) -> tuple[float, float]:
        """Hidden state: armature current at the end of the last step [A], its step size [s]."""
        return self.motor.current, self.step_size

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        current, self.step_size = hidden["armature"]
        self.previous = tuple(hidden["previous"])
        self.motor = SampledMotor(self.params, zoh_coefficients(self.params, self.step_size),
                                  current)


OUTPUTS = (
    ("tau_drive", "N.m", "Joint-side drive torque over the last step (its average): N K_t i "
                         "times eta where the motor drives the joint, over eta_back where the "
                         "joint drives it"),
    ("i", "A", "Armature current, average over the last step"),
    ("P_elec", "W", "Electrical power V i into the armature, average over the last step"),
    ("E_in", "J", "Net electrical energy since the start, integral of V i dt (regeneration "
                  "credited)"),
    ("E_drawn", "J", "Energy drawn from a supply that cannot take energy back since the "
                     "start: max(P_elec, 0) times the step size, summed over the steps"),
    ("E_copper", "J", "Armature copper loss since the start, R_a integral of i^2 dt (and "
                      "the armature's magnetic energy when switched off)"),
    ("E_gear", "J", "Transmission loss since the start, integral of (N K_t i - tau_drive) "
                    "omega dt"),
)
# what an output depends on at the start, before any step: the start current's power and
# the transmission's direction
INITIAL_DEPENDENCIES = {"P_elec": ("V",), "tau_drive": ("omega",)}


REGISTRATION = Registration(
    ports=(Port(ANGULAR, "shaft", "tau_drive", "omega"),
           Port(ELECTROMAGNETIC, "armature", "V", "i")),
    reference_run=DocumentedRun(
        "Voltage step 0 -> 3 V at 0.1 s on the standing drive (4.9 A); the joint speed then "
        "ramps 0 -> 2 rad/s over 0.5-1.0 s (the back-EMF, 5.7 V, exceeds the voltage: the "
        "drive regenerates); voltage 0 from 1.25 s (braking); the drive switched off over "
        "1.35-1.4 s (no current, no effort) and on again.",
        ("V", "omega", "enable"),
        ((0.0, 0.0, 0.0, 1), (0.1, 0.0, 0.0, 1), (0.1, 3.0, 0.0, 1), (0.5, 3.0, 0.0, 1),
         (1.0, 3.0, 2.0, 1), (1.25, 3.0, 2.0, 1), (1.25, 0.0, 2.0, 1), (1.35, 0.0, 2.0, 1),
         (1.35, 0.0, 2.0, 0), (1.4, 0.0, 2.0, 0), (1.4, 0.0, 2.0, 1), (1.5, 0.0, 2.0, 1))),
    moving_run=Run({}, {"V": 12.0, "omega": 1.0}, 2.0),
    # a joint speed inside the transmission's blend at standstill (STUCK_SPEED / N), where the
    # start effort depends on it
    dependency_probes=(Run({}, {"V": 5.0, "omega": 0.001}, 0.05),),
    initial_parameters={"i0": 0.5, "eta": 0.7, "eta_back": 0.6},
)
