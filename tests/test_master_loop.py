"""The master's loop: a step the FMU refuses stops the run with the FMI function's name and
status and the FMU's own message (the loop calls the FMU's C functions directly), and each
joint's fused drive step gives what `DiscretePID.update` and `SampledMotor.step` give."""

from __future__ import annotations

import ctypes
import math
import random

import numpy as np
import pytest

from fmu_src.units.controller.pid import DiscretePID, PIDGains, tustin_coefficients
from fmu_src.units.drive.dc_motor import MotorParameters, SampledMotor, zoh_coefficients
from harness import bench
from harness.fmu.loader import FMUCallError
from harness.run import loop, master
from harness.run import scenario_files as scenarios


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
    monkeypatch.setattr(master, "assemble", lambda *args: assembled.append(args))
    with pytest.raises(FMUCallError) as failure:
        master.run(scenario, scenario.variant("self_regulating"))
    assert failure.value.function == "fmi2SetReal" and failure.value.status == 3  # fmi2Error
    assert "input tau_drive = nan N.m is not a finite number in [-inf, inf]" in str(
        failure.value) and "\n" not in str(failure.value)
    assert not assembled  # nothing made of a failed run


def test_the_fused_drive_step_is_the_pid_and_the_motor_to_the_last_bit() -> None:
    """Random errors and speeds, large enough to saturate the output both ways (so that the
    anti-windup holds the integrator) and small enough to leave it: every voltage, current
    and effort equal to the bit to those of the PID followed by the motor."""
    motor_parameters, dt, limit = MotorParameters(), 1e-3, 24.0
    gains = PIDGains(Kp=300.0, Ki=2000.0, Kd=8.0, T_f=2e-3)
    pid = DiscretePID(gains, tustin_coefficients(gains, dt), limit)
    pid.reset(0.01, integral=3.0)
    motor = SampledMotor(motor_parameters, zoh_coefficients(motor_parameters, dt), 1.5)
    rng = random.Random(14)
    n = 2000
    references = [0.2 * math.sin(k / 50.0) for k in range(n + 1)]
    positions = [rng.uniform(-0.3, 0.3) * (k % 400 < 200) for k in range(n)]
    speeds = [rng.uniform(-1.0, 1.0) for _ in range(n)]
    efforts = (ctypes.c_double * 2)()
    drive = loop.DriveLoop(pid, motor, references, efforts, 1)
    saturated = 0
    for k in range(n):
        drive.step(k, positions[k], speeds[k])
        start = motor.current
        voltage = pid.update(references[k] - positions[k])
        current, effort = motor.step(voltage, speeds[k])
        saturated += pid.saturated
        assert (drive.voltage[k], drive.start_current[k], drive.current[k], drive.effort[k],
                efforts[1]) == (voltage, start, current, effort, effort)
        assert (drive.position[k], drive.speed[k]) == (positions[k], speeds[k])
    assert drive.start_current[n] == motor.current and efforts[0] == 0.0
    assert 0 < saturated < n  # both regimes were crossed


def test_the_master_share_replays_each_run_to_the_bit() -> None:
    """`bench.master_share` on demian2022's variants: the replay of each run's efforts ends
    where the run ended (it raises otherwise), and the master's share is the difference of
    the closed-loop step's cost and its FMU calls'. That the FMU calls cost less than the whole
    step is a timing figure: `make bench` checks it (harness.bench.targets.master_share_checks)."""
    table = bench.master_share(repeats=1, scenario_name="demian2022")
    assert list(table.variant) == list(scenarios.load("demian2022").variants)
    assert (table.fmu_calls_us_per_step > 0.0).all()
    np.testing.assert_allclose(table.master_us_per_step,
                               table.us_per_step - table.fmu_calls_us_per_step, rtol=1e-9)
