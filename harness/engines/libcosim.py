"""The libcosim engines (DNV's Open Simulation Platform, through libcosimpy): the variant's
system of FMUs (`harness.engines.system`) written as OspSystemStructure.xml or an .ssp archive
into build/system/<scenario>/ and run at the fixed step (`run`), or under libcosim's ECCO
algorithm, whose step adapts to the energy residuals of the power bonds between each drive
and its joint (`run_ecco`, `EccoSettings`, docs/results.md#variable-steps-ecco)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from harness.engines.plan import RunPlan
from harness.engines.result import RunResult
from harness.engines.settings import SOURCES, EccoSettings
from harness.engines.system import (
    SYSTEM_DIR,
    System,
    describe,
    model_variables,
    recorded_every,
    recorded_variables,
    system_result,
)
from harness.engines.writers import write_osp, write_ssp
from harness.errors import UserError

ECCO_CHUNK = 1000  # an ECCO run's steps between two reads of its time series


def run(plan: RunPlan, progress: Callable[[int], None] | None = None,
        source: str = "osp") -> RunResult:
    """The planned run's system run by libcosim at the fixed step, from its OSP description
    (build/system/<scenario>/osp/<variant>/OspSystemStructure.xml) or its SSP archive
    (build/system/<scenario>/<variant>.ssp)."""
    if source not in SOURCES:
        raise UserError(f"--source = {source!r} must be one of {', '.join(SOURCES)}")
    system = describe(plan)
    files, variant = SYSTEM_DIR / plan.scenario.name, plan.variant.name
    path = (write_osp(system, files / "osp" / variant) if source == "osp"
            else write_ssp(system, files / f"{variant}.ssp"))
    result = run_libcosim(system, path)
    if progress is not None:
        progress(plan.n_steps)
    return result


def run_ecco(plan: RunPlan, progress: Callable[[int], None] | None = None,
             ecco: EccoSettings | None = None) -> RunResult:
    """The planned run's system run by libcosim under ECCO (default EccoSettings), the
    plan's step its first step; its OSP description with the ECCO configuration is written
    to build/system/<scenario>/osp-ecco/<variant>/ for libcosim's own command line, the run
    is made through libcosimpy's API (`ecco_execution`)."""
    ecco = ecco or EccoSettings()
    ecco.check()
    system = describe(plan, ecco)
    write_osp(system, SYSTEM_DIR / plan.scenario.name / "osp-ecco" / plan.variant.name)
    result = run_libcosim(system)
    if progress is not None:
        progress(plan.n_steps)
    return result


def _time_series(observer, slave: int, reference: int, steps: int, first: int = 0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Samples of steps first..steps from a libcosim time-series observer, and their times
    [s].

    libcosimpy 0.0.6 trims its answer by the number of zero step numbers, which drops one
    real sample when step 0 is among them: ask again from where the answer stopped.
    """
    values: list[float] = []
    times: list[int] = []
    while len(values) <= steps - first:
        at = first + len(values)
        stamps, numbers, samples = observer.time_series_real_samples(
            slave, reference, at, steps + 2 - at)
        if not numbers or numbers[0] != at:
            raise RuntimeError(f"libcosim time series of variable {reference} ends at step "
                               f"{at} of {steps}")
        values.extend(samples)
        times.extend(stamps)
    count = steps + 1 - first
    return np.asarray(values[:count]), np.asarray(times[:count]) * 1e-9


def _ecco_steps(execution, system: System, series, last, index: dict[str, int],
                reals: list, bools: list) -> tuple[np.ndarray, pd.DataFrame, pd.DataFrame]:
    """Step an ECCO execution up to the first communication point at or after the task's
    end (libcosim does not shorten the last step); every point's time [s], Real values
    (drained from the time-series observer every ECCO_CHUNK steps) and Booleans (read from
    the last-value observer after each step; at t = 0, the scenario's)."""
    end = round(system.scenario.duration * 1e9)
    columns: dict[str, list[np.ndarray]] = {f"{c}.{v.name}": [] for c, v in reals}
    times: list[np.ndarray] = []
    boolean_rows = []
    steps = drained = 0
    while execution.status().current_time < end:
        if not execution.step(1):
            raise RuntimeError(f"libcosim (ECCO) failed in the step after t = "
                               f"{execution.status().current_time * 1e-9} s")
        steps += 1
        boolean_rows.append({v.name: bool(value) for (c, v) in bools
                             for value in last.last_boolean_values(index[c],
                                                                   [v.valueReference])})
        if steps - drained == ECCO_CHUNK or execution.status().current_time >= end:
            first = 0 if drained == 0 else drained + 1
            for c, v in reals:
                values, stamps = _time_series(series, index[c], v.valueReference, steps, first)
                columns[f"{c}.{v.name}"].append(values)
            times.append(stamps)
            drained = steps
    start = system.plan.inputs
    first_row = {name: bool(start[name][0]) if name in start else value
                 for name, value in boolean_rows[0].items()}
    return (np.concatenate(times),
            pd.DataFrame({name: np.concatenate(parts) for name, parts in columns.items()}),
            pd.DataFrame([first_row, *boolean_rows]))


def ecco_execution(system: System) -> tuple[object, object]:
    """A libcosim execution of the system under ECCO, made through libcosimpy's API: its
    FMUs as local slaves with the system's parameters, its connections, and one power bond
    per `System.bonds` (source: the drive, its effort out and flow in; sink: the mechanism).
    Returns (execution, algorithm): the algorithm must live as long as the execution.

    Not from the OSP file: libcosim 0.0.6's parser refuses a file with more than one power
    bond (it checks the count of bonds against that of their names while still adding
    them), and active_relocation and demian2022 have two.
    """
    from libcosimpy.CosimAlgorithm import CosimAlgorithm, EccoParams
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimSlave import CosimLocalSlave

    settings = system.ecco
    elements = settings.osp_elements(system.step_size)
    algorithm = CosimAlgorithm.create_ecco_algorithm(EccoParams(
        safety_factor=settings.safety_factor, step_size=elements["StepSize"],
        min_step_size=settings.min_step, max_step_size=settings.max_step,
        min_change_rate=settings.min_change_rate, max_change_rate=settings.max_change_rate,
        abs_tolerance=settings.abs_tolerance, rel_tolerance=settings.rel_tolerance,
        p_gain=settings.p_gain, i_gain=settings.i_gain))
    execution = CosimExecution.from_algorithm(algorithm)
    variables = model_variables(system)
    index = {component: execution.add_local_slave(CosimLocalSlave(
        str(system.fmus[model]), component)) for component, model in system.models.items()}
    setters = {"Real": execution.real_initial_value, "Integer": execution.integer_initial_value,
               "Boolean": execution.boolean_initial_value}
    for component, values in system.parameters.items():
        for name, value in values.items():
            variable = variables[component][name]
            setters[variable.type](index[component], variable.valueReference, value)
    connect = {"Real": execution.connect_real_variables,
               "Boolean": execution.connect_boolean_variables,
               "Integer": execution.connect_integer_variables}
    for start, output, end, input_name in system.connections:
        source = variables[start][output]
        if connect[source.type](index[start], source.valueReference, index[end],
                                variables[end][input_name].valueReference) != 0:
            raise RuntimeError(f"libcosim refused the connection {start}.{output} -> "
                               f"{end}.{input_name}")
    for bond in system.bonds:
        source, sink = variables[bond.source], variables[bond.sink]
        if algorithm.add_power_bond(
                index[bond.source], source[bond.source_effort].valueReference,
                source[bond.source_flow].valueReference, index[bond.sink],
                sink[bond.sink_flow].valueReference,
                sink[bond.sink_effort].valueReference) != 0:
            raise RuntimeError(f"libcosim refused the power bond {bond.name}")
    return execution, algorithm


def run_libcosim(system: System, source: Path | None = None) -> RunResult:
    """Run an OspSystemStructure.xml or an .ssp archive in libcosim at the fixed step, or
    an ECCO system (system.ecco; source None) through libcosimpy's API (`ecco_execution`).

    Real variables come from a time-series observer at every step; Booleans, which it does
    not record, from a last-value observer at the recording points (at t = 0, which that
    observer cannot see, the scenario's inputs and the values after the first step). The
    last-value observer also exposes every variable for reading, which libcosim's ECCO needs
    for the bonds' inputs (it reads them without exposing them).
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    nanoseconds = round(system.step_size * 1e9)
    algorithm = None
    if system.ecco is not None:
        execution, algorithm = ecco_execution(system)
    elif source.suffix == ".ssp":  # libcosim needs the step size given for an SSP
        execution = CosimExecution.from_ssp_file(str(source), step_size=nanoseconds)
    else:
        execution = CosimExecution.from_osp_config_file(str(source))
    steps = round(system.scenario.duration / system.step_size)
    every = recorded_every(system)
    series = CosimObserver.create_time_series(
        buffer_size=steps + 1 if system.ecco is None else ECCO_CHUNK + 2)
    last = CosimObserver.create_last_value()
    execution.add_observer(series)
    execution.add_observer(last)
    variables = model_variables(system)
    index = {c: execution.slave_index_from_instance_name(c) for c in system.models}
    reals, bools = [], []
    for component, names in recorded_variables(system, variables).items():
        for name in names:
            variable = variables[component][name]
            (reals if variable.type == "Real" else bools).append((component, variable))
    for component, variable in reals:
        series.start_time_series(index[component], variable.valueReference,
                                 CosimVariableType.REAL)
    if system.ecco is not None:
        times, frame, booleans = _ecco_steps(execution, system, series, last, index, reals,
                                             bools)
        del execution, algorithm  # the execution first
        return system_result(system, frame, booleans, [], times)
    boolean_rows = []
    for chunk in range(steps // every):
        if not execution.step(every):
            raise RuntimeError(f"libcosim failed in the steps after t = "
                               f"{chunk * every * system.step_size} s")
        boolean_rows.append({v.name: bool(value) for (c, v) in bools
                             for value in last.last_boolean_values(index[c],
                                                                   [v.valueReference])})
    if steps % every and not execution.step(steps % every):
        raise RuntimeError("libcosim failed in the last steps")
    start = system.plan.inputs
    first = {name: bool(start[name][0]) if name in start else value
             for name, value in boolean_rows[0].items()} if boolean_rows else {}
    frame = pd.DataFrame({f"{c}.{v.name}": _time_series(series, index[c], v.valueReference,
                                                        steps)[0]
                          for c, v in reals})
    return system_result(system, frame, pd.DataFrame([first, *boolean_rows]), [])
