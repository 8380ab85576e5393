"""The FMPy master's loop: a step the FMU refuses stops the run with the FMI function's name
and status and the FMU's own message, and each joint's drive records what its PID and motor
held and carried at every step."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from fmu_src.units.controller.pid import DiscretePID, PIDGains, tustin_coefficients
from fmu_src.units.drive.dc_motor import MotorParameters, SampledMotor, zoh_coefficients
from harness import bench, scenarios
from harness.drive.trace import SampledDrive
from harness.engines import fmpy_master
from harness.engines.plan import prepare
from harness.fmu.loader import FMUCallError


def test_a_refused_step_stops_the_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """From step 5 on the reference is NaN, so the drive hands the mechanism a NaN effort,
    which SelfRegulatingBalancer refuses when it is set (fmi2SetReal returns fmi2Error, before
    any fmi2DoStep takes it): one line naming tau_drive and its range."""
    reference = scenarios.Scenario.reference

    def failing(self: scenarios.Scenario, times: np.ndarray, joint: int | str = 0) -> np.ndarray:
        values = reference(self, times, joint)
        values[5:] = math.nan
        return values

    monkeypatch.setattr(scenarios.Scenario, "reference", failing)
    scenario = scenarios.load("franchetti2021")
    assembled = []
    monkeypatch.setattr(fmpy_master, "assemble", lambda *args: assembled.append(args))
    with pytest.raises(FMUCallError) as failure:
        fmpy_master.run(prepare(scenario, scenario.variant("self_regulating")))
    assert failure.value.function == "fmi2SetReal" and failure.value.status == 3  # fmi2Error
    assert "input tau_drive = nan N.m is not a finite number in [-inf, inf]" in str(
        failure.value) and "\n" not in str(failure.value)
    assert not assembled  # nothing made of a failed run


def test_the_drive_records_what_its_pid_and_motor_held_and_carried() -> None:
    """Random errors and speeds, large enough to saturate the output both ways (so that the
    anti-windup holds the integrator) and small enough to leave it: at every step the drive's
    record holds the voltage, the current at the step's start and its average, the effort,
    and the joint's position and speed, as a PID and a motor of its own stepped alongside
    give them; the record ends with the current after the last step."""
    motor_parameters, dt, limit = MotorParameters(), 1e-3, 24.0
    gains = PIDGains(Kp=300.0, Ki=2000.0, Kd=8.0, T_f=2e-3)

    def pid_and_motor() -> tuple[DiscretePID, SampledMotor]:
        pid = DiscretePID(gains, tustin_coefficients(gains, dt), limit)
        pid.reset(0.01, integral=3.0)
        return pid, SampledMotor(motor_parameters, zoh_coefficients(motor_parameters, dt), 1.5)

    pid, motor = pid_and_motor()
    rng = random.Random(14)
    n = 2000
    references = [0.2 * math.sin(k / 50.0) for k in range(n + 1)]
    positions = [rng.uniform(-0.3, 0.3) * (k % 400 < 200) for k in range(n)]
    speeds = [rng.uniform(-1.0, 1.0) for _ in range(n)]
    drive = SampledDrive(*pid_and_motor(), references)
    saturated = 0
    for k in range(n):
        returned = drive.step(k, positions[k], speeds[k])
        start = motor.current
        voltage = pid.update(references[k] - positions[k])
        current, effort = motor.step(voltage, speeds[k])
        saturated += pid.saturated
        assert (drive.voltage[k], drive.start_current[k], drive.current[k], drive.effort[k],
                returned) == (voltage, start, current, effort, effort)
        assert (drive.position[k], drive.speed[k]) == (positions[k], speeds[k])
    drive.end(0.5, -0.25)
    assert drive.start_current[n] == motor.current
    assert (drive.position[n], drive.speed[n]) == (0.5, -0.25)
    assert 0 < saturated < n  # both regimes were crossed


@pytest.mark.slow   # about 4 s: demian2022's runs, twice each
def test_the_master_share_replays_each_run_to_the_bit() -> None:
    """`bench.master_share` on demian2022's variants: the replay of each run's efforts ends
    where the run ended (it raises otherwise), and the master's share is the difference of
    the closed-loop step's cost and its FMU calls', as a fraction of the step too."""
    table = bench.master_share(repeats=1, scenario_name="demian2022")
    assert list(table.variant) == list(scenarios.load("demian2022").variants)
    assert (table.fmu_calls_us_per_step > 0.0).all()
    np.testing.assert_allclose(table.master_us_per_step,
                               table.us_per_step - table.fmu_calls_us_per_step, rtol=1e-9)
    np.testing.assert_allclose(table.master_share,
                               table.master_us_per_step / table.us_per_step, rtol=1e-9)
