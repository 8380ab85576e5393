"""FMI 2.0 Co-Simulation slave of the discrete PID position controller
(docs/drive_and_controller.md).

A thin layer over `fmu_src.units.controller.pid`, the controller the harness uses: at
fmi2DoStep(t, h) it samples the position error e = theta_ref - theta of its inputs at t, and the
output V after the step is the voltage it holds over [t, t + h], limited to +-V_supply (Tustin
coefficients at the step size actually given, recomputed when it changes). A master that steps
this FMU first and passes V to the drive for the same interval (Gauss-Seidel) reproduces the
harness's co-simulation. Before the first step V is the output at rest, Kp e + integral0,
limited.

The controller starts at rest with the error of its inputs at initialisation (no derivative
kick) and the integrator at `integral0`: R_a times the current that holds the static load
starts the drive in equilibrium, as the harness does.

With `enable` false over a step the drive is switched off: V is 0 and the controller holds
its state; switched on again it starts from the error then with its integral reset (no
derivative kick), as the harness's drive does (harness.drive.trace.SampledDrive).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fmu_src.fmi.slave import ModelSlave
from fmu_src.fmi.vocabulary import DefaultExperiment
from fmu_src.mechanism import DocumentedRun, Quantity, Registration, Run
from fmu_src.parameters import parameter
from fmu_src.units.controller.pid import DiscretePID, PIDGains, PIDState, tustin_coefficients

STEP_SIZE = 1e-3  # default communication step [s], the harness's


@dataclass(frozen=True)
class ControllerParameters:
    """Gains, output limit and initial integrator state.

    The default gains are harness.drive.controller.design_pid (triple closed-loop pole at 25
    rad/s, derivative filter at 10 times that) for the default motor of
    fmu_src.units.drive.dc_motor driving the SelfRegulatingBalancer's default link: inertia
    J_link + J_rotor N^2 = 0.16 + 0.04127535 kg m^2, friction d_link = 0.01 N m s/rad. V_supply
    is the default motor's. A test checks that they still equal what the harness designs. """

    Kp: float = parameter(80.20664122012941, "V/rad", "Proportional gain", min=0.0)
    Ki: float = parameter(668.3886768344117, "V/(rad.s)", "Integral gain", min=0.0)
    Kd: float = parameter(0.33124035749069575, "V.s/rad", "Derivative gain", min=0.0)
    T_f: float = parameter(0.004, "s", "Time constant of the derivative filter", min=0.0,
                           min_exclusive=True)
    V_supply: float = parameter(24.0, "V", "Output limit: |V| <= V_supply", min=0.0,
                                min_exclusive=True)
    integral0: float = parameter(0.0, "V", "Integrator state at the start (R_a i_hold starts "
                                 "the drive holding a static load)")


class PositionController(ModelSlave):
    """PID with filtered derivative and conditional-integration anti-windup,
    C(s) = Kp + Ki/s + Kd s/(T_f s + 1), discretised by Tustin at the communication step."""

    parameters_type = ControllerParameters
    hidden_state = ("controller",)
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.0, step_size=STEP_SIZE)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Discrete PID position controller with filtered derivative, "
                            "output limit and anti-windup (Tustin at the communication step)")
        self.add_input("theta_ref", 0.0, "rad", "Reference joint angle")
        self.add_input("theta", 0.0, "rad", "Measured joint angle")
        self.add_input("enable", True, None, "The drive is on; off (false), V is 0 and the "
                       "controller holds (switched on, it restarts with its integral reset)")
        # V is held over the last step, so of no input now; at the start it is the output at
        # rest for the error of the inputs then
        at_start = ("theta_ref", "theta")
        self.add_output("V", "V", "Voltage command held over the last step, limited to "
                        "[-V_supply, V_supply]", initial_depends_on=at_start)
        self.add_output("saturated", None, "V is at its limit; the integrator holds while the "
                        "error pushes further into the limit", initial_depends_on=at_start)
        self.pid: DiscretePID | None = None
        self.step_size = 0.0  # the step size the PID's coefficients are for [s]

    def error(self) -> float:
        """The position error of the inputs, theta_ref - theta [rad]."""
        return float(self.theta_ref) - float(self.theta)

    def new_pid(self) -> DiscretePID:
        """The PID of the current parameters at the current step size, before any sample."""
        p = self.params
        gains = PIDGains(p.Kp, p.Ki, p.Kd, p.T_f)
        return DiscretePID(gains, tustin_coefficients(gains, self.step_size), p.V_supply)

    def initialise(self, params: ControllerParameters) -> None:
        self.step_size = STEP_SIZE
        self.pid = self.new_pid()
        error = self.error()
        self.pid.reset(error, params.integral0)
        self.on = True  # the drive was on before the first step
        at_rest = params.Kp * error + params.integral0
        self.V = min(max(at_rest, -params.V_supply), params.V_supply)
        self.saturated = self.V != at_rest

    def step(self, dt: float) -> None:
        if dt != self.step_size:
            self.pid.coefficients = tustin_coefficients(self.pid.gains, dt)
            self.step_size = dt
        error = self.error()
        if not self.enable:
            self.on, self.V, self.saturated = False, 0.0, False
            return
        if not self.on:  # switched on: a bumpless start
            self.pid.reset(error)
            self.on = True
        self.V = self.pid.update(error)
        self.saturated = self.pid.saturated

    @property
    def controller(self) -> tuple[PIDState, float, bool]:
        """Hidden state: the PID's state after the last sample, its step size [s], whether
        the drive was on over the last step."""
        return self.pid.state(), self.step_size, self.on

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        state, self.step_size, self.on = hidden["controller"]
        self.pid = self.new_pid()
        self.pid.restore(PIDState(*state))


REGISTRATION = Registration(
    ports=(Quantity("Voltage", "command", ("V",)),),
    reference_run=DocumentedRun(
        "Reference step 0 -> 0.5 rad at 0.1 s; the measured angle follows as a ramp over "
        "0.1-0.6 s (the output saturates while the error is large, the integrator holds; "
        "near the limit `saturated` toggles from step to step, so every step is recorded); "
        "the drive switched off over 0.7-0.8 s (V = 0) and on again (integral reset).",
        ("theta_ref", "theta", "enable"),
        ((0.0, 0.0, 0.0, 1), (0.1, 0.0, 0.0, 1), (0.1, 0.5, 0.0, 1), (0.6, 0.5, 0.5, 1),
         (0.7, 0.5, 0.5, 1), (0.7, 0.5, 0.5, 0), (0.8, 0.5, 0.5, 0), (0.8, 0.5, 0.5, 1),
         (1.0, 0.5, 0.5, 1)),
        output_interval=1e-3),
    moving_run=Run({}, {"theta_ref": 0.002}, 2.0),  # unsaturated
    dependency_probes=(Run({}, {"theta_ref": 0.05, "theta": 0.01}, 0.05),),  # unsaturated
)
