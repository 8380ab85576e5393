"""One energy account: the drive's energies of `fmu_src.units.drive.dc_motor` (per step and as
rates), the
metrics summed from a `DriveTrace`, and effort metrics named by joint kind."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fmu_src.units.drive.dc_motor import (
    MotorParameters,
    SampledMotor,
    drive_powers,
    step_energies,
    zoh_coefficients,
)
from fmu_src.units.sequencer.scenario import Joint
from harness.drive.metrics import drive_metrics
from harness.drive.motor import start_currents
from harness.drive.trace import DriveTrace

MOTOR = MotorParameters()
REVOLUTE = Joint("theta", "theta", "omega", "tau_drive", "theta0", "J_link", "d_link",
                 "J_drive", "tau_gravity", True)
PRISMATIC = replace(REVOLUTE, name="q", kind="prismatic", motor="lead_screw")


def run_motor(voltage: np.ndarray, omega: np.ndarray, dt: float,
              i0: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(start currents, n + 1; average currents; efforts) of the sampled motor."""
    motor = SampledMotor(MOTOR, zoh_coefficients(MOTOR, dt), i0)
    starts, averages, efforts = [], [], []
    for v, w in zip(voltage.tolist(), omega.tolist(), strict=True):
        starts.append(motor.current)
        average, effort = motor.step(v, w)
        averages.append(average)
        efforts.append(effort)
    return np.append(starts, motor.current), np.array(averages), np.array(efforts)


def blocked_rotor_trace(joint: Joint, dt: float, n: int, volts: float) -> DriveTrace:
    """A voltage step from rest on a blocked rotor."""
    voltage, still = np.full(n, volts), np.zeros(n + 1)
    starts, averages, efforts = run_motor(voltage, still[:n], dt)
    return DriveTrace(joint, MOTOR, dt, voltage, averages, efforts, starts, still, still, still)


def test_copper_loss_of_a_trace_is_the_exact_integral() -> None:
    """Blocked rotor, 2 V from rest at 1 ms (5 armature time constants per step): i(t) =
    I (1 - exp(-t/tau)) and R_a times the integral of i^2 in closed form. The square of the
    step-average current would miss the rise within the first step (0.3 % here)."""
    dt, n, volts = 1e-3, 20, 2.0
    trace = blocked_rotor_trace(REVOLUTE, dt, n, volts)
    tau, final, t_end = MOTOR.L_a / MOTOR.R_a, volts / MOTOR.R_a, n * dt
    copper = MOTOR.R_a * final ** 2 * (t_end - 2 * tau * (1 - math.exp(-t_end / tau))
                                       + tau / 2 * (1 - math.exp(-2 * t_end / tau)))
    metrics = drive_metrics(trace)
    assert metrics["E_copper"] == pytest.approx(copper, rel=1e-12)
    assert metrics["E_in"] == pytest.approx(copper + 0.5 * MOTOR.L_a * final ** 2, rel=1e-12)
    assert metrics["E_inductor"] == pytest.approx(0.5 * MOTOR.L_a * final ** 2, rel=1e-12)
    assert metrics["E_mech"] == metrics["W_link"] == 0.0
    average_squared = MOTOR.R_a * np.sum(trace.current ** 2) * dt
    assert abs(average_squared / copper - 1.0) > 2e-3


def test_effort_metrics_are_named_by_joint_kind() -> None:
    torque = drive_metrics(blocked_rotor_trace(REVOLUTE, 1e-3, 5, 2.0))
    force = drive_metrics(blocked_rotor_trace(PRISMATIC, 1e-3, 5, 2.0))
    assert {"tau_peak", "tau_rms"} <= set(torque) and not {"F_peak", "F_rms"} & set(torque)
    assert {"F_peak", "F_rms"} <= set(force) and not {"tau_peak", "tau_rms"} & set(force)
    assert force["F_peak"] == torque["tau_peak"] == pytest.approx(
        MOTOR.torque_per_amp * 2.0 / MOTOR.R_a, rel=1e-6)  # the same numbers, named apart


def test_step_energies_work_alike_on_floats_and_arrays() -> None:
    """Motoring and regenerating steps: the array call gives every float call's result, and
    the drawn energy is V i dt where positive, 0 where the motor regenerates."""
    rng = np.random.default_rng(3)
    n, dt = 200, 1e-3
    voltage, omega = rng.uniform(-24.0, 24.0, n), rng.uniform(-5.0, 5.0, n)
    starts, averages, efforts = run_motor(voltage, omega, dt, i0=1.0)
    travel = omega * dt
    arrays = step_energies(MOTOR, dt, voltage, omega, starts[:-1], averages, efforts, travel)
    floats = [step_energies(MOTOR, dt, *values) for values in
              zip(voltage.tolist(), omega.tolist(), starts[:-1].tolist(), averages.tolist(),
                  efforts.tolist(), travel.tolist(), strict=True)]
    np.testing.assert_array_equal(np.array(arrays).T, np.array(floats))
    electrical = voltage * averages * dt
    assert (electrical < 0).any() and (electrical > 0).any()
    np.testing.assert_allclose(arrays.E_drawn, np.maximum(electrical, 0.0), rtol=1e-15, atol=0)
    np.testing.assert_allclose(arrays.W_link, efforts * travel, rtol=1e-14, atol=0)
    # the armature's balance per step: V i dt = copper + back-EMF work + magnetic energy
    back_emf = MOTOR.back_emf_per_link_speed * omega * averages * dt
    magnetic = 0.5 * MOTOR.L_a * np.diff(starts ** 2)
    np.testing.assert_allclose(arrays.E_copper, electrical - back_emf - magnetic, rtol=1e-9,
                               atol=1e-12)


def test_powers_are_the_rates_of_the_energies() -> None:
    """On a step much shorter than L_a/R_a the step's energies over dt tend to the powers."""
    dt, voltage, omega, i0 = 1e-12, 12.0, 2.0, 1.5
    motor = SampledMotor(MOTOR, zoh_coefficients(MOTOR, dt), i0)
    average, effort = motor.step(voltage, omega)
    energies = step_energies(MOTOR, dt, voltage, omega, i0, average, effort, omega * dt)
    powers = drive_powers(MOTOR, voltage, i0, MOTOR.torque_per_amp * i0, omega)
    for energy, power in zip(energies, powers, strict=True):
        assert energy / dt == pytest.approx(power, rel=1e-6)


def test_start_currents_are_recovered_from_the_averages() -> None:
    """What the system's result does with the DcMotorDrive FMU's average currents."""
    rng = np.random.default_rng(4)
    dt, n = 1e-3, 300
    voltage, omega = rng.uniform(-24.0, 24.0, n), rng.uniform(-5.0, 5.0, n)
    starts, averages, _ = run_motor(voltage, omega, dt, i0=-2.0)
    np.testing.assert_allclose(start_currents(MOTOR, dt, voltage, omega, averages), starts,
                               rtol=0, atol=1e-12 * np.abs(starts).max())


def test_a_current_decaying_at_rest_reaches_zero_not_a_magnitude_the_fmus_refuse() -> None:
    """With no voltage and no speed the armature current decays by exp(-R_a dt / L_a) per
    step; after enough steps it falls below 1e-50 A, which the mechanism FMUs refuse as an
    input's effort (docs/robustness.md). A ciupitu2018 study task held the arm upright (no
    gravity torque) long enough for that: the motor hands on 0 instead, exactly, and every
    non-zero value it hands on is at least 1e-50."""
    dt = 1e-3
    motor = SampledMotor(MOTOR, zoh_coefficients(MOTOR, dt), 1.0)
    decay = math.exp(-MOTOR.R_a * dt / MOTOR.L_a)
    steps = math.ceil(math.log(1e-50) / math.log(decay)) + 10   # past 1e-50 A from 1 A
    values = [value for _ in range(steps) for value in motor.step(0.0, 0.0)]
    assert motor.current == 0.0
    assert values[-2:] == [0.0, 0.0]
    assert all(v == 0.0 or abs(v) >= 1e-50 for v in values)
    assert any(0.0 < abs(v) < 1e-45 for v in values)   # it did pass through the small ones
