"""The drive model and the PID: one definition, two discretisations that agree, and the
design rule's closed-loop poles."""

from __future__ import annotations

import math

import control as ct
import numpy as np
import pytest

from fmu_src.units.controller.pid import PIDGains, tustin_coefficients
from fmu_src.units.drive.dc_motor import MotorParameters, SampledMotor, zoh_coefficients
from harness.drive.controller import (
    ControllerDesign,
    design_pid,
    design_report,
    discrete_pid,
    discretise,
    reduced_plant,
)
from harness.drive.motor import MOTORS, motor_system
from harness.drive.motor import discretise as discretise_motor

MOTOR = MotorParameters()
LINK_INERTIA = 0.16 + MOTOR.J_drive  # Franchetti link plus reflected rotor [kg m^2]


@pytest.mark.parametrize("dt", [1e-4, 1e-3, 4e-3])
def test_closed_form_zoh_equals_control_c2d(dt: float) -> None:
    closed = zoh_coefficients(MOTOR, dt)
    c2d = discretise_motor(MOTOR, dt)
    np.testing.assert_allclose(closed, c2d, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("dt", [1e-4, 1e-3, 4e-3])
def test_closed_form_tustin_equals_control_c2d(dt: float) -> None:
    gains = PIDGains(Kp=80.0, Ki=670.0, Kd=0.33, T_f=0.004)
    np.testing.assert_allclose(tustin_coefficients(gains, dt), discretise(gains, dt),
                               rtol=1e-12, atol=1e-12)


def test_motor_reaches_stall_current_and_conserves_energy() -> None:
    # blocked rotor: i -> V / R_a; over the run V i dt = R i^2 dt + magnetic energy 1/2 L i^2
    dt, volts = 1e-4, 2.0
    motor = SampledMotor(MOTOR, zoh_coefficients(MOTOR, dt))
    supplied = 0.0
    for _ in range(100):  # 10 ms = 50 electrical time constants
        average, torque = motor.step(volts, 0.0)
        supplied += volts * average * dt
    assert motor.current == pytest.approx(volts / MOTOR.R_a, rel=1e-12)
    assert torque == pytest.approx(MOTOR.eta * MOTOR.N * MOTOR.K_t * volts / MOTOR.R_a,
                                   rel=1e-9)
    # copper loss integrated exactly: i(t) = I (1 - exp(-t/tau))
    tau, final, t_end = MOTOR.L_a / MOTOR.R_a, volts / MOTOR.R_a, 100 * dt
    copper = MOTOR.R_a * final ** 2 * (t_end - 2 * tau * (1 - math.exp(-t_end / tau))
                                       + tau / 2 * (1 - math.exp(-2 * t_end / tau)))
    assert supplied == pytest.approx(copper + 0.5 * MOTOR.L_a * motor.current ** 2, rel=1e-6)


def test_motor_system_has_named_signals_and_the_armature_pole() -> None:
    sys = motor_system(MOTOR)
    assert sys.input_labels == ["V", "omega"] and sys.output_labels == ["tau_drive", "i"]
    assert ct.poles(sys)[0] == pytest.approx(-MOTOR.R_a / MOTOR.L_a)
    # DC gain from V to the stalled torque: eta N K_t / R_a
    assert ct.dcgain(sys)[0][0] == pytest.approx(MOTOR.torque_per_amp / MOTOR.R_a)


def test_design_places_reduced_closed_loop_poles_at_omega_c() -> None:
    design = ControllerDesign()
    gains = design_pid(MOTOR, LINK_INERTIA, 0.01, design)
    alpha, beta = reduced_plant(MOTOR, LINK_INERTIA, 0.01)
    plant = ct.tf([beta], [1.0, alpha, 0.0])
    pid = ct.tf([gains.Kd, gains.Kp, gains.Ki], [1.0, 0.0])  # unfiltered, as in the rule
    poles = ct.poles(ct.feedback(pid * plant, 1))
    np.testing.assert_allclose(np.sort(poles.real), [-design.omega_c] * 3, rtol=1e-3)
    # on the full model (armature inductance, derivative filter) the loop stays well damped
    report = design_report(MOTOR, LINK_INERTIA, 0.01, gains)
    assert report["phase_margin_deg"] > 45 and report["max_pole_real"] < 0


def test_overdamped_joint_gets_no_derivative_and_its_third_pole_at_alpha_minus_two_omega_c(
) -> None:
    """The self-locking screw's reflected rotor (33 kg on a 0.5 kg carriage) makes the
    back-EMF damp the joint at alpha = 326 1/s > 3 omega_c: Kd = 0, poles -omega_c (double)
    and -(alpha - 2 omega_c), and the full loop keeps a good margin."""
    motor, mass, friction = MOTORS["trapezoidal_screw"], 0.5, 100.0
    design = ControllerDesign()
    alpha, beta = reduced_plant(motor, mass + motor.J_drive, friction)
    assert alpha > 3 * design.omega_c
    gains = design_pid(motor, mass + motor.J_drive, friction, design)
    assert gains.Kd == 0.0
    pid = ct.tf([gains.Kp, gains.Ki], [1.0, 0.0])
    poles = ct.poles(ct.feedback(pid * ct.tf([beta], [1.0, alpha, 0.0]), 1))
    w = design.omega_c
    np.testing.assert_allclose(np.sort(poles.real), [-(alpha - 2 * w), -w, -w], rtol=1e-3)
    report = design_report(motor, mass + motor.J_drive, friction, gains)
    assert report["phase_margin_deg"] > 45 and report["max_pole_real"] < 0
    # and the discrete PID is a PI: no derivative coefficients
    coefficients = discretise(gains, 1e-3)
    assert coefficients.b0 == coefficients.b1 == 0.0


def test_anti_windup_holds_the_integrator_while_saturated() -> None:
    gains = design_pid(MOTOR, LINK_INERTIA, 0.01)
    pid = discrete_pid(gains, 1e-3, limit=MOTOR.V_supply)
    for _ in range(100):
        assert pid.update(1.0) == MOTOR.V_supply  # 1 rad error saturates at once
    assert pid.saturated
    # the integral only moved on the first sample (from its reset value 0) at most
    assert abs(pid.integral) <= 0.5 * gains.Ki * 1e-3 * 1.0 + 1e-12


def test_bad_motor_parameter_names_the_variable() -> None:
    with pytest.raises(ValueError, match=r"R_a = -1.0 Ohm is outside \(0.0, inf\)"):
        MotorParameters(R_a=-1.0)
    with pytest.raises(ValueError, match=r"eta = 1.5 (1 )?is outside \(0.0, 1.0\]"):
        MotorParameters(eta=1.5)
