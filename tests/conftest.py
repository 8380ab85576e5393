"""Shared helpers for the tests: built FMUs, runs through FMPy, FMI status codes, and the
regression checks against the committed results."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd
import pytest

from fmu_src import integration
from harness import engines, registry
from harness.engines import DEFAULT_STEP
from harness.engines.result import RunResult
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU, FMICallException
from harness.run import results
from harness.run.compare import compare, read_result, report
from harness.run.sizing import stored_drives
from harness.scenarios import Scenario

# fmi2Status codes (FMI 2.0 standard, section 2.1.3)
FMI_OK, FMI_WARNING, FMI_DISCARD, FMI_ERROR, FMI_FATAL = range(5)

SRB = "SelfRegulatingBalancer"


@pytest.fixture(scope="session")
def srb_fmu() -> Path:
    """The built SelfRegulatingBalancer FMU (rebuilt if its sources changed)."""
    return fmu_build.fmu_path(SRB)


def bundled(module: str) -> list[ModuleType]:
    """The modules of this dotted name (`SelfRegulatingBalancer`, `fmu_src.integration`) that
    the FMUs opened in this process run: the runtime imports each FMU's bundle as a package
    _fmu_bundle_<digest of its files> (docs/build.md), one per content."""
    return [found for name, found in list(sys.modules.items())
            if name.startswith("_fmu_bundle_") and name.partition(".")[2] == module]


def open_fmu(path: Path, parameters: Mapping[str, float | bool | str] | None = None,
             instance_name: str = "test") -> CoSimFMU:
    """An initialised instance; parameters and input start values are set in initialisation."""
    fmu = CoSimFMU(path, instance_name=instance_name)
    try:
        fmu.initialize(parameters)
    except Exception:
        fmu.close()
        raise
    return fmu


def run(fmu: CoSimFMU, steps: int, step_size: float, names: Iterable[str],
        start_time: float = 0.0) -> np.ndarray:
    """Step `steps` times; row k holds the named variables after step k (Booleans as 0/1)."""
    names = list(names)
    reals = [i for i, n in enumerate(names) if fmu.variables[n].type == "Real"]
    bools = [i for i, n in enumerate(names) if fmu.variables[n].type == "Boolean"]
    real_refs = fmu.references(names[i] for i in reals)
    bool_refs = fmu.references(names[i] for i in bools)
    rows = np.empty((steps, len(names)))
    slave = fmu.slave
    for k in range(steps):
        fmu.step(start_time + k * step_size, step_size)
        if reals:
            rows[k, reals] = slave.getReal(real_refs)
        if bools:
            rows[k, bools] = slave.getBoolean(bool_refs)
    return rows


def play_sequencer(fmu: CoSimFMU, variant: str, steps: int,
                   step_size: float) -> dict[str, np.ndarray]:
    """Initialise a ScenarioSequencer instance with `variant` and step it `steps` times: every
    output (in the model's order) at t = 0 and after each step. The FMU must log nothing."""
    fmu.initialize({"variant": variant})
    outputs = fmu.names("output")
    rows = [fmu.get(outputs)]
    for k in range(steps):
        fmu.step(k * step_size, step_size)
        rows.append(fmu.get(outputs))
    assert not fmu.messages
    return {name: np.array([row[name] for row in rows]) for name in outputs}


# each mechanism's energy ledger (docs/energy_ledger.md): its terms and their signs; the sum
# stays constant over any input sequence
LEDGER: dict[str, Mapping[str, int]] = {model: r.ledger
                                         for model, r in registry.mechanisms().items()}


def ledger_residual(model: str, out: Mapping[str, float]) -> float:
    """Stored energy + E_loss - W_drive - E_added (- W_worm, - W_adjust) [J]."""
    return sum(sign * out[name] for name, sign in LEDGER[model].items())


def warnings(fmu: CoSimFMU) -> list[str]:
    """The Warning-status messages the FMU has logged."""
    return [m.message for m in fmu.messages if m.status == "Warning"]


def errors(fmu: CoSimFMU) -> list[str]:
    """The Error-status messages the FMU has logged."""
    return [m.message for m in fmu.messages if m.status == "Error"]


def refusal(message: str, function: str) -> str:
    """The slave's own words in the runtime's one line for a refusing exception,
    "<function>: ValueError: <words>" (checked)."""
    called, kind, words = message.split(": ", 2)
    assert (called, kind) == (function, "ValueError"), message
    return words


def serialized_state(fmu: CoSimFMU) -> tuple[bytes, bytes, bytes]:
    """A serialised FMU state of the instance now, in its three parts: the runtime's line
    naming the FMU ("pythonfmu state of FMU <GUID>"), its line of the state machine state and
    time, and the slave's bytes (fmu_src/runtime/fmi2_functions.c)."""
    state = fmu.slave.getFMUstate()
    try:
        serialized = bytes(fmu.slave.serializeFMUstate(state))
    finally:
        fmu.slave.freeFMUstate(state)
    header, machine, body = serialized.split(b"\n", 2)
    assert header == b"pythonfmu state of FMU " + fmu.model_description.guid.encode()
    return header, machine, body


@contextlib.contextmanager
def resumed(fmu: CoSimFMU) -> Iterator[None]:
    """Around a call that must be refused (fmi2Discard or fmi2Error): the slave's state must
    be the same bytes after it, and the FMU state taken before it is set again after, as FMI
    2.0 asks of a host that goes on after such a call (the instance is in the stepFailed or
    error state until then)."""
    taken = fmu.slave.getFMUstate()
    try:
        before = serialized_state(fmu)[2]
        yield
        assert serialized_state(fmu)[2] == before  # the refused call changed nothing
        fmu.slave.setFMUstate(taken)
    finally:
        fmu.slave.freeFMUstate(taken)


def refused_set(fmu: CoSimFMU, values: Mapping[str, float | bool | str],
                function: str = "fmi2SetReal") -> str:
    """Set variables of an initialised instance that must be refused: fmi2Error, one Error
    message without a traceback, the values and the slave's state as they were (`resumed`,
    which lets the run go on); the slave's words in that message."""
    logged = len(fmu.messages)
    before = fmu.get(values)
    with resumed(fmu):
        with pytest.raises(FMICallException) as failure:
            fmu.set(values)
        assert failure.value.status == FMI_ERROR and not fmu.fatal
        (message,) = [m.message for m in fmu.messages[logged:] if m.status == "Error"]
        assert "Traceback" not in message
        assert fmu.get(values) == before
    return refusal(message, function)


def failed_initialisation(model: str, parameters: Mapping[str, float]) -> str:
    """Initialise with parameters that must be refused (fmi2Error, the instance usable for
    nothing but freeing); the slave's words in the one Error message."""
    fmu = CoSimFMU(fmu_build.fmu_path(model))
    try:
        with pytest.raises(FMICallException) as failure:
            fmu.initialize(parameters)
        assert failure.value.status == FMI_ERROR and not fmu.fatal
        (message,) = errors(fmu)
        return refusal(message, "fmi2ExitInitializationMode")
    finally:
        fmu.close()


def fair_run(scenario: Scenario, variant: str, loss_set: str = "ideal",
             engine: str = "fmpy", step_size: float = DEFAULT_STEP, **options: Any
             ) -> RunResult:
    """A run of the variant (scenario: the loss set's) with the drives its committed result
    set ran with (results/<scenario>/drives.csv), by the named engine (the FMPy master by
    default) with its options."""
    return engines.run(engine, scenario, scenario.variant(variant), step_size,
                       drives=committed_drives(scenario, variant, loss_set), **options)


def committed_drives(scenario: Scenario, variant: str, loss_set: str = "ideal"
                     ) -> dict[str, Any]:
    """The drives the variant's committed result set ran with, by joint."""
    folder = results.RESULTS_DIR / scenario.name
    return stored_drives(folder if loss_set == "ideal" else folder / "realistic", variant,
                         loss_set)


def assert_reproduces_committed_summary(scenario: Scenario, runs: Iterable[RunResult],
                                        folder: Path | None = None) -> None:
    """The summary rows of these runs equal those of results/<scenario>/summary.csv (or of
    the result set in folder). Columns the runs alone do not have, per-joint columns of a
    scenario whose variants differ in their joints, are empty in those rows or repeat the
    metric of the variant's one joint."""
    folder = results.RESULTS_DIR / scenario.name if folder is None else folder
    committed = pd.read_csv(folder / "summary.csv")
    fresh = results.summary(runs, scenario.baselines).set_index("variant")
    committed = committed.set_index("variant").loc[fresh.index]
    assert list(fresh.columns) == [c for c in committed.columns if c in fresh.columns]
    for column in (c for c in committed.columns if c not in fresh.columns):
        filled = committed[column].notna()
        if not filled.any():
            continue
        metric = column.rsplit("_", 1)[0]
        assert metric in fresh.columns, column
        if column.startswith("drive"):  # the drive's parts, or whether it does the task
            assert (committed.loc[filled, column].astype(str)
                    == fresh.loc[filled, metric].astype(str)).all(), column
            continue
        np.testing.assert_allclose(committed.loc[filled, column].to_numpy(float),
                                   fresh.loc[filled, metric].to_numpy(float), rtol=1e-6,
                                   atol=1e-9, err_msg=column)
    text = [c for c in fresh.columns if c == "model" or c.startswith("drive")]
    assert fresh[text].fillna("").astype(str).equals(committed[text].fillna("").astype(str))
    numeric = [c for c in fresh.columns if c not in text]
    # the loop is deterministic; 1e-6 allows for another CPU's floating-point library
    np.testing.assert_allclose(fresh[numeric].to_numpy(float),
                               committed[numeric].to_numpy(float), rtol=1e-6, atol=1e-9)


def assert_reproduces_committed_series(scenario: Scenario, run: RunResult,
                                       signals: list[str]) -> None:
    """The run's series equals results/<scenario>/<variant>.csv in these signals (through
    `python -m harness compare`'s comparison)."""
    committed = read_result(results.RESULTS_DIR / scenario.name / f"{run.variant}.csv")
    comparisons = compare(committed, run.series, signals, rtol=1e-6, atol=1e-9)
    assert all(c.passed for c in comparisons), report(comparisons)


def write(path: Path, frame: pd.DataFrame) -> Path:
    """frame written to path as a result CSV (no index column); the path."""
    frame.to_csv(path, index=False)
    return path


# A step may cost at most MAX_SUBSTEPS RK4 sub-steps: well under a second on any machine
# this runs on (the default models take about 10 us per sub-step).
STEP_TIME_LIMIT = 5.0


def refused_step(fmu: CoSimFMU, time_point: float = 0.0, step_size: float = 1e-3) -> str:
    """Take a step that must be refused with Discard within STEP_TIME_LIMIT, logging one
    Error message without a traceback and leaving the slave's state as it was (`resumed`,
    which lets the run go on); that message."""
    logged = len(fmu.messages)
    with resumed(fmu):
        start = time.perf_counter()
        with pytest.raises(FMICallException) as failure:
            fmu.step(time_point, step_size)
        assert time.perf_counter() - start < STEP_TIME_LIMIT
        assert failure.value.status == FMI_DISCARD
    new = [m.message for m in fmu.messages[logged:] if m.status == "Error"]
    assert len(new) == 1
    assert "Traceback" not in new[0]
    return new[0]


def controlled_reference(physics: Any, p: Any, u: Any, start: Any, dt: float,
                         works: tuple[int, ...], constrain: Any = None) -> Any:
    """RK4 over a mechanism's full state (its `derivatives`, constrain after each sub-step)
    over dt [s] from start, with the rate rule's sub-steps raised under the ledger control
    the physics uses (`integration.ledger_controlled`; works: the indices of the works in
    the state): the reference the written-out kernels must equal bit for bit."""
    return integration.ledger_controlled(
        lambda n: integration.integrate_substeps(lambda s: physics.derivatives(p, u, s), start,
                                                 dt, n, constrain),
        lambda s: physics.ledger_terms(p, u, s), works, start,
        integration.first_substeps(dt, physics.characteristic_rate(p, u, start)), dt, p,
        tuple(getattr(u, name) for name in physics.EVENT_INPUTS))
