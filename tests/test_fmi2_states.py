"""The FMI 2.0 state machine the FMUs' runtime enforces (fmu_src/runtime/fmi2_states.c).

The standard's tables of allowed calls (FMI 2.0.x, section 4.2.4 for Co-Simulation, section
3.2.3 for Model Exchange) are written out below as the standard prints them, row by row; the
runtime's own table (dumped by tests/native_host/fmi2_state_table.c) must equal them for
every interface type, state and call. The same C program then makes every call in every
state a synchronous Co-Simulation slave can be in, on the probe FMU: a call the table does not
allow is refused with fmi2Error and a message, any other is not. The cases found by hand
(re-initialising after steps, a step in Initialization Mode, a communication point that is not
the FMU's time) are tested through FMPy on a shipped FMU.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from conftest import FMI_ERROR, SRB, open_fmu
from fmpy import read_model_description

from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU, FMICallException

TESTS = Path(__file__).resolve().parent
TABLE_SOURCE = TESTS / "native_host" / "fmi2_state_table.c"
PROBE = "RuntimeProbe"
DT = 1e-3

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the runtime and the C host are for Linux")

# FMI 2.0.x, section 4.2.4: x allowed, a number allowed under a condition on the variables
# (the slave's to check), blank not allowed
CO_SIMULATION_STATES = ("start/end", "instantiated", "Initialization Mode", "stepComplete",
                        "stepInProgress", "stepFailed", "stepCanceled", "terminated", "error",
                        "fatal")
CO_SIMULATION = """
fmi2GetTypesPlatform         |x |x |x |x |x |x |x |x |x |
fmi2GetVersion               |x |x |x |x |x |x |x |x |x |
fmi2SetDebugLogging          |  |x |x |x |x |x |x |x |x |
fmi2Instantiate              |x |  |  |  |  |  |  |  |  |
fmi2FreeInstance             |  |x |x |x |  |x |x |x |x |
fmi2SetupExperiment          |  |x |  |  |  |  |  |  |  |
fmi2EnterInitializationMode  |  |x |  |  |  |  |  |  |  |
fmi2ExitInitializationMode   |  |  |x |  |  |  |  |  |  |
fmi2Terminate                |  |  |  |x |  |x |  |  |  |
fmi2Reset                    |  |x |x |x |  |x |x |x |x |
fmi2GetReal                  |  |  |2 |x |  |8 |7 |x |7 |
fmi2GetInteger               |  |  |2 |x |  |8 |7 |x |7 |
fmi2GetBoolean               |  |  |2 |x |  |8 |7 |x |7 |
fmi2GetString                |  |  |2 |x |  |8 |7 |x |7 |
fmi2SetReal                  |  |1 |3 |6 |  |  |  |  |  |
fmi2SetInteger               |  |1 |3 |6 |  |  |  |  |  |
fmi2SetBoolean               |  |1 |3 |6 |  |  |  |  |  |
fmi2SetString                |  |1 |3 |6 |  |  |  |  |  |
fmi2GetFMUstate              |  |x |x |x |  |8 |7 |x |7 |
fmi2SetFMUstate              |  |x |x |x |  |x |x |x |x |
fmi2FreeFMUstate             |  |x |x |x |  |x |x |x |x |
fmi2SerializedFMUstateSize   |  |x |x |x |  |x |x |x |x |
fmi2SerializeFMUstate        |  |x |x |x |  |x |x |x |x |
fmi2DeSerializeFMUstate      |  |x |x |x |  |x |x |x |x |
fmi2GetDirectionalDerivative |  |  |x |x |  |8 |7 |x |7 |
fmi2SetRealInputDerivatives  |  |x |x |x |  |  |  |  |  |
fmi2GetRealOutputDerivatives |  |  |  |x |  |8 |x |x |7 |
fmi2DoStep                   |  |  |  |x |  |  |  |  |  |
fmi2CancelStep               |  |  |  |  |x |  |  |  |  |
fmi2GetStatus                |  |  |  |x |x |x |  |x |  |
fmi2GetRealStatus            |  |  |  |x |x |x |  |x |  |
fmi2GetIntegerStatus         |  |  |  |x |x |x |  |x |  |
fmi2GetBooleanStatus         |  |  |  |x |x |x |  |x |  |
fmi2GetStringStatus          |  |  |  |x |x |x |  |x |  |
"""
# FMI 2.0.x, section 3.2.3
MODEL_EXCHANGE_STATES = ("start/end", "instantiated", "Initialization Mode", "Event Mode",
                         "Continuous-Time Mode", "terminated", "error", "fatal")
MODEL_EXCHANGE = """
fmi2GetTypesPlatform              |x |x |x |x |x |x |x |
fmi2GetVersion                    |x |x |x |x |x |x |x |
fmi2SetDebugLogging               |  |x |x |x |x |x |x |
fmi2Instantiate                   |x |  |  |  |  |  |  |
fmi2FreeInstance                  |  |x |x |x |x |x |x |
fmi2SetupExperiment               |  |x |  |  |  |  |  |
fmi2EnterInitializationMode       |  |x |  |  |  |  |  |
fmi2ExitInitializationMode        |  |  |x |  |  |  |  |
fmi2Terminate                     |  |  |  |x |x |  |  |
fmi2Reset                         |  |x |x |x |x |x |x |
fmi2GetReal                       |  |  |2 |x |x |x |7 |
fmi2GetInteger                    |  |  |2 |x |x |x |7 |
fmi2GetBoolean                    |  |  |2 |x |x |x |7 |
fmi2GetString                     |  |  |2 |x |x |x |7 |
fmi2SetReal                       |  |1 |3 |4 |5 |  |  |
fmi2SetInteger                    |  |1 |3 |4 |  |  |  |
fmi2SetBoolean                    |  |1 |3 |4 |  |  |  |
fmi2SetString                     |  |1 |3 |4 |  |  |  |
fmi2GetFMUstate                   |  |x |x |x |x |x |7 |
fmi2SetFMUstate                   |  |x |x |x |x |x |x |
fmi2FreeFMUstate                  |  |x |x |x |x |x |x |
fmi2SerializedFMUstateSize        |  |x |x |x |x |x |x |
fmi2SerializeFMUstate             |  |x |x |x |x |x |x |
fmi2DeSerializeFMUstate           |  |x |x |x |x |x |x |
fmi2GetDirectionalDerivative      |  |  |x |x |x |x |7 |
fmi2EnterEventMode                |  |  |  |x |x |  |  |
fmi2NewDiscreteStates             |  |  |  |x |  |  |  |
fmi2EnterContinuousTimeMode       |  |  |  |x |  |  |  |
fmi2CompletedIntegratorStep       |  |  |  |  |x |  |  |
fmi2SetTime                       |  |  |  |8 |x |  |  |
fmi2SetContinuousStates           |  |  |  |  |x |  |  |
fmi2GetEventIndicators            |  |  |x |x |x |x |7 |
fmi2GetContinuousStates           |  |  |x |x |x |x |7 |
fmi2GetDerivatives                |  |  |x |x |x |x |7 |
fmi2GetNominalsOfContinuousStates |  |x |x |x |x |x |7 |
"""


def standard_table(text: str, states: tuple[str, ...]) -> dict[tuple[str, str], bool]:
    """(state, call) -> allowed, from the rows above (the last column, fatal, is blank in
    every row of the standard: no call is allowed after fmi2Fatal)."""
    table = {}
    for row in text.strip().splitlines():
        call, *cells = (cell.strip() for cell in row.split("|"))
        cells = cells[:-1]  # the text after the last bar
        assert len(cells) == len(states) - 1, row
        for state, cell in zip(states, [*cells, ""]):
            table[state, call] = cell != ""
    return table


STANDARD = {"cs": standard_table(CO_SIMULATION, CO_SIMULATION_STATES),
            "me": standard_table(MODEL_EXCHANGE, MODEL_EXCHANGE_STATES)}
CO_SIMULATION_ONLY = {call for state, call in STANDARD["cs"]} - {
    call for state, call in STANDARD["me"]}
MODEL_EXCHANGE_ONLY = {call for state, call in STANDARD["me"]} - {
    call for state, call in STANDARD["cs"]}


@pytest.fixture(scope="module")
def state_table(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/native_host/fmi2_state_table.c with the runtime's state machine, compiled with
    the compiler the FMU build uses."""
    return fmu_build.zig_cc(TABLE_SOURCE, tmp_path_factory.mktemp("states") / "fmi2_state_table",
                            f"-I{fmu_build.RUNTIME_SOURCE.parent}",
                            fmu_build.STATE_MACHINE_SOURCE, "-ldl")


@pytest.fixture(scope="module")
def probe(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, int], str]:
    """The probe slave built as `make fmu` builds the shipped FMUs, unzipped: its folder,
    value references and GUID."""
    fmu = fmu_build.build(PROBE, tmp_path_factory.mktemp("probe"),
                          TESTS / "data" / "runtime_slaves")
    folder = tmp_path_factory.mktemp("probe_unzipped")
    zipfile.ZipFile(fmu).extractall(folder)
    md = read_model_description(fmu)
    return folder, {v.name: v.valueReference for v in md.modelVariables}, md.guid


def test_the_runtime_holds_the_standards_tables(state_table: Path) -> None:
    """Every (interface type, state, call) of the runtime's table as the standard's: a call
    of the other interface type is allowed in no state."""
    done = subprocess.run([str(state_table), "table"], capture_output=True, text=True,
                          check=True, timeout=60)
    held = {}
    for line in done.stdout.splitlines():
        kind, state, call, allowed = line.split("\t")
        held[kind, state, call] = allowed == "1"
    for kind, only_other in (("cs", MODEL_EXCHANGE_ONLY), ("me", CO_SIMULATION_ONLY)):
        expected = {(kind, state, call): allowed for (state, call), allowed in
                    STANDARD[kind].items()}
        ours = {key: value for key, value in held.items()
                if key[0] == kind and (key[1], key[2]) in STANDARD[kind]}
        assert ours == expected
        assert not [key for key, value in held.items() if key[0] == kind and value
                    and key[2] in only_other]
    assert len(held) == 2 * 12 * 44  # every state of both types, every FMI 2.0 function


def test_every_call_in_every_state_of_a_slave_is_allowed_or_refused_as_the_standard_says(
        state_table: Path, probe: tuple[Path, dict[str, int], str]) -> None:
    """In C, with an empty environment: each of the 30 calls on an instance, in each of the
    7 states a synchronous slave can be in (stepInProgress and stepCanceled need an
    asynchronous one). A call the standard does not allow is fmi2Error with the runtime's
    message; an allowed one is not refused (its own status may be anything: the probe refuses
    what it refuses). After fmi2Fatal every call is fmi2Fatal."""
    folder, refs, guid = probe
    done = subprocess.run([str(state_table), "run", str(folder), PROBE, guid,
                           *(str(refs[n]) for n in ("u", "mode", "text", "flag"))],
                          env={}, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-4000:]
    rows = [line.split("\t") for line in done.stdout.splitlines()]
    assert len(rows) == 7 * 30
    wrong = []
    for state, call, status, refused in rows:
        if state == "fatal":
            if status != "4":
                wrong.append((state, call, status, refused))
            continue
        allowed = STANDARD["cs"][state, call]
        if refused != ("0" if allowed else "1") or (not allowed and status != "3"):
            wrong.append((state, call, status, refused))
    assert wrong == []


# --- the cases found by hand, through FMPy on a shipped FMU --------------------------------


def stepped(steps: int = 100) -> tuple[CoSimFMU, dict[str, float]]:
    """A SelfRegulatingBalancer that moves (k = 0), `steps` steps of DT in, and its theta and
    omega after initialisation."""
    fmu = open_fmu(fmu_build.fmu_path(SRB), {"k": 0.0})
    initial = fmu.get(["theta", "omega"])
    for k in range(steps):
        fmu.step(k * DT, DT)
    return fmu, initial


def refused(call: object, *args: object) -> int:
    """The status of a call that must fail (FMPy raises for any status above Warning)."""
    with pytest.raises(FMICallException) as failure:
        call(*args)  # type: ignore[operator]
    return failure.value.status


def last_error(fmu: CoSimFMU) -> str:
    return [m.message for m in fmu.messages if m.status == "Error"][-1]


@pytest.mark.parametrize("calls", [("exitInitializationMode",),
                                   ("enterInitializationMode", "exitInitializationMode")])
def test_initialising_again_after_steps_is_an_error_that_keeps_the_state(
        calls: tuple[str, ...]) -> None:
    """It used to return OK and start the run over: theta back at its start value."""
    fmu, initial = stepped()
    try:
        moved = fmu.get(["theta", "omega"])
        assert moved["theta"] != initial["theta"]
        logged = len(fmu.messages)
        for call in calls:
            assert refused(getattr(fmu.slave, call)) == FMI_ERROR
        first = f"fmi2{calls[0][0].upper()}{calls[0][1:]}"
        assert fmu.messages[logged].message.startswith(
            f"{first} is not allowed in stepComplete")
        assert fmu.get(["theta", "omega"]) == moved  # read in the error state: allowed
    finally:
        fmu.close()


def test_setup_experiment_after_initialisation_is_an_error() -> None:
    """It used to return OK and move the start time."""
    fmu, _ = stepped(10)
    try:
        assert refused(fmu.slave.setupExperiment, None, 5.0) == FMI_ERROR
        assert "fmi2SetupExperiment is not allowed in stepComplete" in last_error(fmu)
        assert refused(fmu.step, 10 * DT, DT) == FMI_ERROR  # the error state: no more steps
    finally:
        fmu.close()


def test_a_step_in_initialization_mode_is_an_error() -> None:
    """It used to be fmi2Discard (the slave's refusal) instead of the standard's error."""
    fmu = CoSimFMU(fmu_build.fmu_path(SRB))
    try:
        fmu.slave.setupExperiment(startTime=0.0)
        fmu.slave.enterInitializationMode()
        assert refused(fmu.step, 0.0, DT) == FMI_ERROR
        assert "fmi2DoStep is not allowed in Initialization Mode" in last_error(fmu)
    finally:
        fmu.close()


@pytest.mark.parametrize(("first", "second"), [(5.0, None), (0.0, 0.0), (0.0, 2 * DT),
                                               (0.0, DT * (1 + 2e-9)), (math.nan, None),
                                               (-1.0, None), (math.inf, None)])
def test_a_step_must_start_at_the_fmu_time(first: float, second: float | None) -> None:
    """doStep(5, h) at t = 0, a step repeated, a step skipped, a point off by more than the
    stated tolerance (1e-9 of the time), NaN, before the start, infinite: each fmi2Error,
    naming the point and the FMU's time (doStep(5, h) then doStep(0, h) used to be OK)."""
    fmu = open_fmu(fmu_build.fmu_path(SRB))
    try:
        if second is None:
            bad, expected_time = first, 0.0
        else:
            fmu.step(first, DT)
            bad, expected_time = second, first + DT
        assert refused(fmu.step, bad, DT) == FMI_ERROR
        named = re.search(r"currentCommunicationPoint = (\S+) s is not the FMU's time (\S+) s",
                          last_error(fmu))
        assert named, last_error(fmu)
        point, time = (float(value) for value in named.groups())
        assert point == bad or math.isnan(point) and math.isnan(bad)
        assert time == expected_time
    finally:
        fmu.close()


def test_a_host_that_counts_steps_its_own_way_is_followed() -> None:
    """10,000 steps at t0 + k h against the FMU's running sum of the steps (which differ
    by rounding), then at a running sum of the host's own, agreeing within the tolerance."""
    fmu = open_fmu(fmu_build.fmu_path(SRB))
    try:
        h = 1e-3 / 3.0
        for k in range(10_000):
            fmu.step(k * h, h)
        t = 10_000 * h
        for _ in range(1_000):
            fmu.step(t, h)
            t += h
    finally:
        fmu.close()
