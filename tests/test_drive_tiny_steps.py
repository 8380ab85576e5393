"""DcMotorDrive on steps far shorter than the armature time constant L_a/R_a (0.19 ms): the
closed forms used to cancel catastrophically (at 24 V, an average current of 4.1e-5 A over
1e-14 s where the exact value is 1e-9 A, and a negative copper energy at 1e-16 s)."""

from __future__ import annotations

import pytest
from conftest import open_fmu

from fmu_src.units.drive.dc_motor import (
    MotorParameters,
    SampledMotor,
    copper_energy,
    zoh_coefficients,
)
from harness.fmu import build as fmu_build

MOTOR = MotorParameters()
V = 24.0


def taylor(dt: float) -> tuple[float, float]:
    """Average current [A] and copper energy [J] over dt from rest, from the Taylor expansion
    of the armature's response i(t) = V t/L - R V t^2/(2 L^2) + O(t^3) (two terms: the
    neglected ones are below 1e-20 relative at these steps)."""
    R, L = MOTOR.R_a, MOTOR.L_a
    average = V * dt / (2 * L) - R * V * dt ** 2 / (6 * L ** 2)
    copper = R * (V ** 2 * dt ** 3 / (3 * L ** 2) - R * V ** 2 * dt ** 4 / (4 * L ** 3))
    return average, copper


@pytest.mark.parametrize("dt", [1e-16, 1e-14, 1e-12, 1e-9])
def test_average_current_and_copper_energy_on_tiny_steps(dt: float) -> None:
    average, _ = SampledMotor(MOTOR, zoh_coefficients(MOTOR, dt)).step(V, 0.0)
    expected_average, expected_copper = taylor(dt)
    assert average == pytest.approx(expected_average, rel=1e-12)
    assert copper_energy(MOTOR, dt, V, 0.0, 0.0) == pytest.approx(expected_copper, rel=1e-12)


def test_copper_energy_matches_the_energy_balance_on_ordinary_steps() -> None:
    """At 1 ms (no cancellation) the armature's energy balance V i_avg dt = E_copper +
    K_e N omega i_avg dt + L/2 (i_end^2 - i_start^2) gives the same number."""
    dt, i_start, omega = 1e-3, 1.0, 2.0
    motor = SampledMotor(MOTOR, zoh_coefficients(MOTOR, dt), i_start)
    average, _ = motor.step(10.0, omega)
    balance = ((10.0 - MOTOR.back_emf_per_link_speed * omega) * average * dt
               - 0.5 * MOTOR.L_a * (motor.current ** 2 - i_start ** 2))
    assert copper_energy(MOTOR, dt, 10.0, omega, i_start) == pytest.approx(balance, rel=1e-12)


@pytest.mark.parametrize("dt", [1e-16, 1e-14])
def test_drive_fmu_on_a_tiny_step(dt: float) -> None:
    with open_fmu(fmu_build.fmu_path("DcMotorDrive"), {"V": V}) as fmu:
        fmu.step(0.0, dt)
        values = fmu.get(["i", "E_copper"])
    expected_average, expected_copper = taylor(dt)
    assert values["i"] == pytest.approx(expected_average, rel=1e-12)
    assert values["E_copper"] == pytest.approx(expected_copper, rel=1e-12)
