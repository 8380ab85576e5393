"""Discrete PID position controller: the one definition of its difference equation
(standard library only).

C(s) = Kp + Ki/s + Kd s/(T_f s + 1), each term discretised by Tustin at the communication
step; the output is limited to +-limit and the integrator stops integrating while the output
is saturated in the direction of the error (conditional-integration anti-windup).

The harness designs the gains with python-control and discretises with `control.c2d`; the
`PositionController` FMU uses the closed form of `tustin_coefficients`; the tests check that
both agree.
"""

from __future__ import annotations

from typing import NamedTuple


class PIDGains(NamedTuple):
    """PID gains, in volts per radian (or per metre) of position error."""

    Kp: float   # [V/rad]
    Ki: float   # [V/(rad s)]
    Kd: float   # [V s/rad]
    T_f: float  # derivative filter time constant [s]


class PIDCoefficients(NamedTuple):
    """Difference equation at one step: D[k] = -a1 D[k-1] + b0 e[k] + b1 e[k-1];
    I[k] = I[k-1] + half_ki_dt (e[k] + e[k-1])."""

    b0: float
    b1: float
    a1: float
    half_ki_dt: float


def tustin_coefficients(gains: PIDGains, dt: float) -> PIDCoefficients:
    """Tustin discretisation at dt [s] in closed form (s = 2/dt (z-1)/(z+1))."""
    tau = 2.0 * gains.T_f / dt
    b0 = 2.0 * gains.Kd / dt / (tau + 1.0)
    return PIDCoefficients(b0, -b0, (1.0 - tau) / (tau + 1.0), 0.5 * gains.Ki * dt)


class PIDState(NamedTuple):
    """What the PID carries from one sample to the next."""

    integral: float        # integrator output I[k] [V]
    previous_error: float  # e[k] [rad]
    derivative: float      # filtered derivative term D[k] [V]
    saturated: bool        # output at the limit at sample k


class DiscretePID:
    """The PID difference equation with output limit and anti-windup."""

    def __init__(self, gains: PIDGains, coefficients: PIDCoefficients, limit: float) -> None:
        self.gains = gains
        self.coefficients = coefficients
        self.limit = limit
        self.integral = 0.0
        self._previous_error = 0.0
        self._derivative = 0.0
        self.saturated = False

    def reset(self, error: float = 0.0, integral: float = 0.0) -> None:
        """Start from rest with the given error (no derivative kick) and integral [V]."""
        self.integral = integral
        self._previous_error = error
        self._derivative = 0.0

    def update(self, error: float) -> float:
        """Output for the position error at this sample, limited to +-limit."""
        b0, b1, a1, half_ki_dt = self.coefficients
        previous, limit = self._previous_error, self.limit
        derivative = self._derivative = -a1 * self._derivative + b0 * error + b1 * previous
        candidate = self.integral + half_ki_dt * (error + previous)
        unclamped = self.gains.Kp * error + candidate + derivative
        # min(max(unclamped, -limit), limit), without two calls: the master's loop runs this
        # at every step of every joint
        output = limit if unclamped > limit else -limit if unclamped < -limit else unclamped
        saturated = self.saturated = output != unclamped
        if not saturated or (unclamped > 0) != (error > 0):
            self.integral = candidate
        self._previous_error = error
        return output

    def state(self) -> PIDState:
        """The state after the last sample (for saving and restoring)."""
        return PIDState(self.integral, self._previous_error, self._derivative, self.saturated)

    def restore(self, state: PIDState) -> None:
        """Continue from a state returned by `state`."""
        self.integral, self._previous_error, self._derivative, self.saturated = state
