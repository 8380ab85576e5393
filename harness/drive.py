"""DC motor with gearbox (python-control) and its sampled form for the co-simulation.

Armature: L di/dt = V - R_a i - K_e N omega; link-side torque tau_drive = eta N K_t i
(SPEC.md section 6). Inputs (V, omega), outputs (tau_drive, i), state i.

Default motor: one coherent small geared DC motor, a 60 W class 24 V graphite-brush motor
with a 3-stage planetary gearhead (the data of the maxon RE 30 / 24 V datasheet, #310007:
R_a = 0.611 Ohm, L = 0.119 mH, K_t = 25.9 mN m/A, rotor inertia 33.5 g cm^2, nominal
current 3.44 A; gear ratio 111:1). At the link that gives 2.87 N m/A, 9.9 N m at the motor's
nominal current (the unbalanced link with 1 kg needs up to 9.3 N m), a no-load speed of
8.3 rad/s at 24 V (the task peaks at 0.4 rad/s), and J_drive = J_rotor N^2 = 0.0413 kg m^2.

Gear efficiency: eta multiplies the torque both ways in this linear model, so eta < 1 would
make a back-driven gearbox return more energy than it receives. The default is eta = 1 and
the gearbox's losses are left to the link's viscous friction; set eta < 1 only for studies
where the drive never regenerates.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import control as ct
import numpy as np


@dataclass(frozen=True)
class MotorParameters:
    """Geared DC motor, SI units."""

    R_a: float = 0.611        # armature resistance [Ohm]
    L_a: float = 0.119e-3     # armature inductance [H]
    K_t: float = 0.0259       # torque constant [N m/A] (= back-EMF constant [V s/rad], SI)
    J_rotor: float = 33.5e-7  # rotor inertia [kg m^2]
    N: float = 111.0          # gear ratio, motor turns per link turn
    eta: float = 1.0          # gearbox torque efficiency (see module docstring)
    V_supply: float = 24.0    # supply voltage, |V| <= V_supply [V]

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not np.isfinite(value) or value <= 0.0:
                raise ValueError(f"motor parameter {name} = {value} is outside (0, inf)")
        if self.eta > 1.0:
            raise ValueError(f"motor parameter eta = {self.eta} is outside (0, 1]")

    @property
    def J_drive(self) -> float:
        """Rotor inertia reflected to the link, J_rotor N^2 [kg m^2]."""
        return self.J_rotor * self.N ** 2

    @property
    def torque_per_amp(self) -> float:
        """Link-side torque per armature ampere, eta N K_t [N m/A]."""
        return self.eta * self.N * self.K_t

    @property
    def back_emf_per_link_speed(self) -> float:
        """Armature back-EMF per link angular velocity, K_e N [V s/rad]."""
        return self.K_t * self.N


def motor_system(motor: MotorParameters) -> ct.StateSpace:
    """Continuous motor model with named signals: inputs (V, omega), outputs (tau_drive, i)."""
    A = [[-motor.R_a / motor.L_a]]
    B = [[1.0 / motor.L_a, -motor.back_emf_per_link_speed / motor.L_a]]
    C = [[motor.torque_per_amp], [1.0]]
    return ct.ss(A, B, C, 0.0, inputs=["V", "omega"], outputs=["tau_drive", "i"],
                 states=["i"], name="motor")


class SampledMotor:
    """The motor under zero-order-hold inputs, stepped one communication interval at a time.

    The armature time constant L/R_a (0.19 ms by default) is shorter than a 1 ms step, so
    the current moves within a step. The model is discretised exactly (python-control c2d,
    zoh) together with the integral of the current, which gives the step-average current:
    the drive torque applied over the step is its average, and V i_avg dt is the exact
    electrical energy of the step.
    """

    def __init__(self, motor: MotorParameters, dt: float) -> None:
        self.motor = motor
        self.dt = dt
        sys = motor_system(motor)
        # augmented with q = integral of i dt, so that (q[k+1] - q[k]) / dt = average current
        A = np.block([[sys.A, np.zeros((1, 1))], [np.array([[1.0]]), np.zeros((1, 1))]])
        B = np.vstack([sys.B, np.zeros((1, 2))])
        discrete = ct.c2d(ct.ss(A, B, np.eye(2), np.zeros((2, 2))), dt, method="zoh")
        # plain floats: this runs once per communication step
        (self._a, _), (self._avg_a, _) = (discrete.A / np.array([[1.0], [dt]])).tolist()
        (self._b_v, self._b_w), (self._avg_b_v, self._avg_b_w) = (
            discrete.B / np.array([[1.0], [dt]])).tolist()
        self.current = 0.0

    def step(self, voltage: float, omega: float) -> tuple[float, float]:
        """Advance one step with V and omega held; returns (average current [A], torque [N m])."""
        i0 = self.current
        average = self._avg_a * i0 + self._avg_b_v * voltage + self._avg_b_w * omega
        self.current = self._a * i0 + self._b_v * voltage + self._b_w * omega
        return average, self.motor.torque_per_amp * average
