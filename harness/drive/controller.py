"""Position controller: PID with filtered derivative and anti-windup, designed with
python-control from the linearised drive + link model and discretised at the step.

Design rule (pole placement on the reduced plant). Neglecting the armature inductance
(L/R_a = 0.19 ms, far above the loop's bandwidth) and the balanced link's gravity, the
plant from voltage to angle is

    G(s) = beta / (s (s + alpha)),  beta = K_tau / (J R_a),
    alpha = (R_a d_link + K_tau K_e N) / (J R_a),

with K_tau = eta N K_t and J the total link-side inertia. The same rule holds for a
prismatic joint driven through a lead screw (N in rad/m): J is then the joint's mass plus
the reflected rotor J_rotor N^2 [kg], d_link its viscous friction [N s/m], K_tau a force per
ampere [N/A], and the gains are volts per metre of error; alpha stays in 1/s.
With C(s) = Kp + Ki/s + Kd s the closed loop is s^3 + (alpha + beta Kd) s^2 + beta Kp s
+ beta Ki; placing its three poles at -omega_c gives Kd = (3 omega_c - alpha)/beta,
Kp = 3 omega_c^2/beta, Ki = omega_c^3/beta. A plant damped by its own back-EMF beyond that,
alpha > 3 omega_c (a screw whose reflected rotor dominates the joint), would get a negative
Kd; it gets Kd = 0 instead and the poles at -omega_c (double) and -(alpha - 2 omega_c):
Kp = (2 (alpha - 2 omega_c) omega_c + omega_c^2)/beta, Ki = (alpha - 2 omega_c) omega_c^2/beta.
The derivative is filtered with
T_f = 1/(derivative_filter_ratio omega_c). There is no gravity feedforward: what balancing
saves must show up in the drive. The full model (inductance, filter) is checked with
python-control (closed-loop poles, margins) in `design_report`.

Discretisation: Tustin (ct.c2d) of each term at the communication step; the difference equation,
voltage limit and anti-windup are `fmu_src.units.controller.pid.DiscretePID` (shared with the
`PositionController` FMU). """

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

from fmu_src.parameters import check_ranges, parameter
from fmu_src.units.controller.pid import DiscretePID, PIDCoefficients, PIDGains
from fmu_src.units.drive.dc_motor import steady_current
from harness.drive.motor import MotorParameters, motor_system
from harness.errors import UserError


@dataclass(frozen=True)
class ControllerDesign:
    """Design targets: closed-loop pole location and derivative filter ratio, both positive
    (ValueError naming the field otherwise: a pole at or right of 0 is no design)."""

    omega_c: float = parameter(25.0, "rad/s", "Triple closed-loop pole at -omega_c", min=0.0,
                               min_exclusive=True)
    derivative_filter_ratio: float = parameter(10.0, "1", "Derivative filter pole at ratio "
                                               "times omega_c", min=0.0, min_exclusive=True)

    def __post_init__(self) -> None:
        check_ranges(self)


def reduced_plant(motor: MotorParameters, inertia: float, d_link: float) -> tuple[float, float]:
    """(alpha [1/s], beta [rad/(V s^2)] or [m/(V s^2)]) of G(s) = beta / (s (s + alpha)).

    inertia: joint-side inertia [kg m^2], or mass [kg] for a lead-screw joint; d_link: its
    viscous friction [N m s/rad] or [N s/m].
    """
    # without inductance the armature carries its steady current: tau = K_tau i(V, omega)
    k_tau = motor.torque_per_amp
    per_volt, per_speed = steady_current(motor, 1.0, 0.0), steady_current(motor, 0.0, 1.0)
    return (d_link - k_tau * per_speed) / inertia, k_tau * per_volt / inertia


def design_pid(motor: MotorParameters, inertia: float, d_link: float,
               design: ControllerDesign = ControllerDesign()) -> PIDGains:
    """PID gains placing the reduced closed loop's poles at -omega_c (triple).

    inertia [kg m^2 or kg] and d_link [N m s/rad or N s/m] as in `reduced_plant`. Where the plant's
    own damping alpha exceeds 3 omega_c, Kd = 0 and the third pole goes to -(alpha - 2 omega_c).
    """
    if not (inertia > 0.0 and d_link >= 0.0):
        raise UserError(f"joint inertia = {inertia} must be in (0, inf) and friction = "
                        f"{d_link} in [0, inf)")
    alpha, beta = reduced_plant(motor, inertia, d_link)
    w = design.omega_c
    T_f = 1.0 / (design.derivative_filter_ratio * w)
    if alpha > 3 * w:
        third = alpha - 2 * w
        return PIDGains(Kp=(2 * third * w + w ** 2) / beta, Ki=third * w ** 2 / beta, Kd=0.0,
                        T_f=T_f)
    return PIDGains(Kp=3 * w ** 2 / beta, Ki=w ** 3 / beta, Kd=(3 * w - alpha) / beta, T_f=T_f)


def pid_transfer_function(gains: PIDGains) -> ct.TransferFunction:
    """C(s) = Kp + Ki/s + Kd s/(T_f s + 1)."""
    s = ct.tf("s")
    return gains.Kp + gains.Ki / s + gains.Kd * s / (gains.T_f * s + 1)


def plant_system(motor: MotorParameters, inertia: float, d_link: float) -> ct.StateSpace:
    """Full linear plant V -> theta: the motor in feedback with the link inertia."""
    link = ct.ss([[0.0, 1.0], [0.0, -d_link / inertia]], [[0.0], [1.0 / inertia]],
                 np.eye(2), 0.0, inputs=["tau_drive"], outputs=["theta", "omega"],
                 states=["theta", "omega"], name="link")
    return ct.interconnect([motor_system(motor), link], inputs=["V"], outputs=["theta"],
                           name="plant", check_unused=False)


def design_report(motor: MotorParameters, inertia: float, d_link: float,
                  gains: PIDGains) -> dict[str, float]:
    """Checks of the design on the full model: margins and slowest closed-loop pole."""
    loop = pid_transfer_function(gains) * ct.tf(plant_system(motor, inertia, d_link))
    gm, pm, _, wc = ct.margin(loop)
    poles = ct.poles(ct.feedback(loop, 1))
    return {"phase_margin_deg": float(pm), "gain_margin": float(gm),
            "crossover_rad_s": float(wc), "slowest_pole_rad_s": float(min(-poles.real)),
            "max_pole_real": float(max(poles.real))}


def discretise(gains: PIDGains, dt: float) -> PIDCoefficients:
    """Tustin difference-equation coefficients at dt [s] from control.c2d (with Kd = 0 the
    filter s / (T_f s + 1) is discretised alone, c2d dropping a zero numerator, and its
    numerator coefficients are 0)."""
    used = 1.0 if gains.Kd == 0.0 else 0.0
    derivative = ct.c2d(ct.tf([gains.Kd + used, 0.0], [gains.T_f, 1.0]), dt, method="tustin")
    integral = ct.c2d(ct.tf([gains.Ki], [1.0, 0.0]), dt, method="tustin")
    (b0, b1), (_, a1) = np.ravel(derivative.num[0][0]), np.ravel(derivative.den[0][0])
    keep = 1.0 - used
    return PIDCoefficients(float(keep * b0), float(keep * b1), float(a1),
                           float(np.ravel(integral.num[0][0])[0]))


def discrete_pid(gains: PIDGains, dt: float, limit: float) -> DiscretePID:
    """The PID of `gains` at step dt [s] with output limit +-limit [V]."""
    return DiscretePID(gains, discretise(gains, dt), limit)
