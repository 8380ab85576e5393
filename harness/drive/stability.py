"""Whether a joint's sampled drive loop holds at a communication step: the linear map of one
step of the fixed-step master (`harness.drive.trace.SampledDrive` on a joint), and its
spectral radius.

Per step of h, from the joint's position theta_k and speed omega_k: the discrete PID
(`fmu_src.units.controller.pid.DiscretePID`, Tustin) gives V_k from e_k = -theta_k; the
armature's zero-order hold (`harness.drive.motor.discretise`) gives the current at the step's
end and its average with V_k and omega_k held; the joint, of inertia J and viscous friction
d, moves under the effort N K_t i_avg held over the step (exactly: the matrix exponential of
J theta'' = tau - d theta'). Its state is (i, theta, omega, the PID's integral, last error and
derivative term); the loop holds where every eigenvalue of the step's map lies inside the
unit circle. Linearised: no voltage limit, a lossless transmission (its largest gain) and no
gravity or spring moment, which the PID holds as a slow load; a step beyond the bound makes
the master's joint diverge (franchetti2021 at 0.5 s: theta 3873 rad after 6 s, refused by the
FMU only then).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from fmu_src.units.controller.pid import PIDGains
from fmu_src.units.drive.dc_motor import MotorParameters
from harness.drive import controller
from harness.drive import motor as motors

# the step's map [i, theta, omega, integral, last error, derivative term]
I, THETA, OMEGA, INTEGRAL, ERROR, DERIVATIVE = range(6)


def step_map(motor: MotorParameters, gains: PIDGains, inertia: float, friction: float,
             step: float) -> np.ndarray:
    """The 6 x 6 map of one master step (module docstring); inertia [kg m^2 or kg] with the
    drive's reflected rotor, friction [N m s/rad or N s/m], step [s]."""
    pid = controller.discretise(gains, step)
    zoh = motors.discretise(motor, step)
    unit = np.eye(6)
    error = -unit[THETA]
    derivative = -pid.a1 * unit[DERIVATIVE] + pid.b0 * error + pid.b1 * unit[ERROR]
    integral = unit[INTEGRAL] + pid.half_ki_dt * (error + unit[ERROR])
    voltage = gains.Kp * error + integral + derivative
    current = zoh.a * unit[I] + zoh.b_v * voltage + zoh.b_w * unit[OMEGA]
    average = zoh.avg_a * unit[I] + zoh.avg_b_v * voltage + zoh.avg_b_w * unit[OMEGA]
    effort = motor.standstill_torque_per_amp * average
    # the joint over the step with the effort held: [theta, omega, effort] through expm
    joint = expm(np.array([[0.0, 1.0, 0.0], [0.0, -friction / inertia, 1.0 / inertia],
                           [0.0, 0.0, 0.0]]) * step)
    moved = joint[:2, :2] @ np.vstack([unit[THETA], unit[OMEGA]]) + np.outer(joint[:2, 2],
                                                                             effort)
    return np.vstack([current, moved, integral, error, derivative])


def spectral_radius(motor: MotorParameters, gains: PIDGains, inertia: float,
                    friction: float, step: float) -> float:
    """The largest eigenvalue magnitude of `step_map`: below 1 where the loop holds."""
    return float(np.max(np.abs(np.linalg.eigvals(step_map(motor, gains, inertia, friction,
                                                          step)))))


def largest_stable_step(motor: MotorParameters, gains: PIDGains, inertia: float,
                        friction: float, unstable: float) -> float:
    """The largest step [s] below `unstable` (a step the loop does not hold) that it holds,
    to 1 %, by bisection on the step's logarithm from 1 us."""
    low, high = 1e-6, unstable
    while high / low > 1.01:
        middle = float(np.sqrt(low * high))
        if spectral_radius(motor, gains, inertia, friction, middle) < 1.0:
            low = middle
        else:
            high = middle
    return low
