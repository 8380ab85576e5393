"""Hosts that add up their time (t += h, as fmuCheck and OMSimulator do) reach a phase start
a little early: 13.99999999999768 s after 14 000 steps of 1 ms. The scenario and the
ScenarioSequencer FMU must still switch phases (and the locks) at the same step as a host
that computes the time as i h (FMPy) or in integer nanoseconds (libcosim)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fmu_src.units.sequencer import scenario as core
from harness import scenarios
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU

# [s] decimal and non-binary steps; every phase start of the shipped scenarios is on their grid
STEPS = (1e-2, 2e-3, 1e-3, 5e-4, 1e-4, 0.1, 1.0 / 30.0, 1.0 / 60.0)


def added_up(step: float, n: int) -> list[float]:
    """The times 0, h, 2h, ... nh of a host that adds the step to its clock [s]."""
    times, t = [0.0], 0.0
    for _ in range(n):
        t += step
        times.append(t)
    return times


@pytest.mark.parametrize("name", scenarios.available())
@pytest.mark.parametrize("step", STEPS)
def test_added_up_and_exact_times_switch_phases_at_the_same_step(name: str, step: float
                                                                 ) -> None:
    scenario = scenarios.load(name)
    tolerance = core.STEP_TIME_TOLERANCE * step
    added = added_up(step, round(scenario.duration / step))
    early = 0  # phase starts the added-up clock reaches before the exact time
    for k, (_, start, _) in enumerate(scenario.phase_times()[1:], start=1):
        switch = round(start / step)  # the step that reaches the phase start
        assert abs(switch * step - start) < 1e-9 * step, "phase start off the step grid"
        early += added[switch] < start
        for i in (switch - 1, switch):
            expected = k if i == switch else k - 1
            assert scenario._phase_at(added[i], tolerance) == expected, (start, i)
            assert scenario._phase_at(i * step, tolerance) == expected, (start, i)
    if (name, step) == ("franchetti2021", 1e-3):
        assert early > 0  # the case a host meets: the test exercises the tolerance


def test_the_tolerance_is_a_small_fraction_of_the_step() -> None:
    """A time clearly before a phase start (a tenth of a step) stays in the earlier phase."""
    scenario = scenarios.load("franchetti2021")
    step = 1e-3
    tolerance = core.STEP_TIME_TOLERANCE * step
    assert scenario._phase_at(14.0 - 0.1 * step, tolerance) == 1
    assert scenario._phase_at(14.0 - 1e-9, tolerance) == 2
    assert scenario._phase_at(14.0 - 1e-9) == 1  # without a tolerance: the exact comparison


def play(fmu: CoSimFMU, times: list[float], names: list[str]) -> np.ndarray:
    """Step through the given communication points; the named outputs after each step."""
    fmu.initialize({"variant": "self_regulating"})
    rows = []
    for t0, t1 in zip(times[:-1], times[1:], strict=True):
        fmu.step(t0, t1 - t0)
        rows.append(list(fmu.get(names).values()))
    assert not fmu.messages
    return np.array(rows, dtype=float)


def test_the_sequencer_switches_the_locks_at_the_same_step_with_added_up_time() -> None:
    """franchetti2021 to 20.5 s at 1 ms: slider and pulley are released at 14 s and locked
    at 20 s at the same step whether the host adds up its time or not."""
    step, n = 1e-3, 20500
    path: Path = fmu_build.fmu_path("ScenarioSequencer")
    names = ["slider_locked", "pulley_locked", "payload", "counterweight_added"]
    with CoSimFMU(path, "added_up") as fmu:
        added = play(fmu, added_up(step, n), names)
    with CoSimFMU(path, "exact") as fmu:
        exact = play(fmu, [i * step for i in range(n + 1)], names)
    assert np.array_equal(added[:, :2], exact[:, :2])
    np.testing.assert_allclose(added[:, 2:], exact[:, 2:], rtol=0.0, atol=1e-9)
    # row r holds the outputs at (r + 1) h: released at 14 s (row 13999), locked at 20 s
    for lock in (0, 1):
        assert np.flatnonzero(np.diff(exact[:, lock])).tolist() == [13998, 19998]
