"""Position controller: PID with filtered derivative and anti-windup, designed with
python-control from the linearised drive + link model and discretised at the step.

Design rule (pole placement on the reduced plant). Neglecting the armature inductance
(L/R_a = 0.19 ms, far above the loop's bandwidth) and the balanced link's gravity, the
plant from voltage to angle is

    G(s) = beta / (s (s + alpha)),  beta = K_tau / (J R_a),
    alpha = (R_a d_link + K_tau K_e N) / (J R_a),

with K_tau = eta N K_t and J the total link-side inertia. With C(s) = Kp + Ki/s + Kd s the
closed loop is s^3 + (alpha + beta Kd) s^2 + beta Kp s + beta Ki; placing its three poles
at -omega_c gives Kd = (3 omega_c - alpha)/beta, Kp = 3 omega_c^2/beta, Ki = omega_c^3/beta.
The derivative is filtered with T_f = 1/(derivative_filter_ratio omega_c). There is no gravity
feedforward: what balancing saves must show up in the drive. The full model (inductance,
filter) is checked with python-control (closed-loop poles, margins) in `design_report`.

Discretisation: Tustin (ct.c2d) of each term at the communication step; the integrator
stops integrating while the voltage is saturated in the direction of the error
(conditional-integration anti-windup).
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

from harness.drive import MotorParameters, motor_system


@dataclass(frozen=True)
class PIDGains:
    """PID gains in volts per radian of position error."""

    Kp: float  # [V/rad]
    Ki: float  # [V/(rad s)]
    Kd: float  # [V s/rad]
    T_f: float  # derivative filter time constant [s]


@dataclass(frozen=True)
class ControllerDesign:
    """Design targets: closed-loop pole location and derivative filter ratio."""

    omega_c: float = 25.0               # triple closed-loop pole [rad/s]
    derivative_filter_ratio: float = 10.0  # filter pole at ratio * omega_c


def reduced_plant(motor: MotorParameters, inertia: float, d_link: float) -> tuple[float, float]:
    """(alpha [1/s], beta [rad/(V s^2)]) of G(s) = beta / (s (s + alpha))."""
    k_tau = motor.torque_per_amp
    alpha = (motor.R_a * d_link + k_tau * motor.back_emf_per_link_speed) / (inertia * motor.R_a)
    return alpha, k_tau / (inertia * motor.R_a)


def design_pid(motor: MotorParameters, inertia: float, d_link: float,
               design: ControllerDesign = ControllerDesign()) -> PIDGains:
    """PID gains placing the reduced closed loop's poles at -omega_c (triple)."""
    alpha, beta = reduced_plant(motor, inertia, d_link)
    w = design.omega_c
    return PIDGains(Kp=3 * w ** 2 / beta, Ki=w ** 3 / beta, Kd=(3 * w - alpha) / beta,
                    T_f=1.0 / (design.derivative_filter_ratio * w))


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


class DiscretePID:
    """The PID of `gains`, discretised by Tustin at dt, with voltage limit and anti-windup."""

    def __init__(self, gains: PIDGains, dt: float, limit: float) -> None:
        self.gains = gains
        self.limit = limit
        derivative = ct.c2d(ct.tf([gains.Kd, 0.0], [gains.T_f, 1.0]), dt, method="tustin")
        # first-order section y[k] = -a1 y[k-1] + b0 e[k] + b1 e[k-1]
        (b0, b1), (_, a1) = np.ravel(derivative.num[0][0]), np.ravel(derivative.den[0][0])
        self._d = (float(b0), float(b1), float(a1))
        self._half_ki_dt = 0.5 * gains.Ki * dt  # Tustin integrator
        self.integral = 0.0
        self._previous_error = 0.0
        self._derivative = 0.0
        self.saturated = False

    def reset(self, error: float = 0.0) -> None:
        """Start from rest with the given error (no derivative kick at start)."""
        self.integral = 0.0
        self._previous_error = error
        self._derivative = 0.0

    def update(self, error: float) -> float:
        """Voltage command for the position error [rad] at this sample, limited to +-limit."""
        b0, b1, a1 = self._d
        self._derivative = -a1 * self._derivative + b0 * error + b1 * self._previous_error
        candidate = self.integral + self._half_ki_dt * (error + self._previous_error)
        unclamped = self.gains.Kp * error + candidate + self._derivative
        voltage = min(max(unclamped, -self.limit), self.limit)
        self.saturated = voltage != unclamped
        if not self.saturated or (unclamped > 0) != (error > 0):
            self.integral = candidate
        self._previous_error = error
        return voltage
