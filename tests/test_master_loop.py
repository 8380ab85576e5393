"""The master's loop calls the FMU's C functions directly: a step the FMU refuses must still
stop the run with the FMI function's name and status, and the FMU's own message."""

from __future__ import annotations

import math

import pytest

from harness import master, scenarios
from harness.fmi import FMUCallError


def test_a_refused_step_stops_the_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """From step 5 on the drive hands the mechanism a NaN effort, which SelfRegulatingBalancer
    refuses at fmi2DoStep (fmi2Discard, worse than fmi2Warning)."""
    drive_step = master.DriveLoop.step

    def failing(self: master.DriveLoop, k: int, position: float, speed: float) -> float:
        effort = drive_step(self, k, position, speed)
        return math.nan if k >= 5 else effort

    monkeypatch.setattr(master.DriveLoop, "step", failing)
    scenario = scenarios.load("franchetti2021")
    assembled = []
    monkeypatch.setattr(master, "assemble", lambda *args: assembled.append(args))
    with pytest.raises(FMUCallError) as failure:
        master.run(scenario, scenario.variant("self_regulating"))
    assert failure.value.function == "fmi2DoStep" and failure.value.status > 1
    assert "tau_drive" in str(failure.value) and "nan" in str(failure.value).lower()
    assert not assembled  # nothing made of a failed run
