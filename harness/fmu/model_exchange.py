"""A mechanism FMU run as Model Exchange in FMPy, and as Co-Simulation with the same inputs,
through a scenario's input sequence (docs/model_exchange.md).

The mechanism alone, open loop. Its inputs are a staircase: on each interval [t_j, t_j+1) of
a co-simulation run's recorded points, every joint's effort as the run held it over the step
that starts at t_j (`efforts`) and the scenario's inputs at t_j (locks, payload: the
mechanism's discrete inputs). In FMPy's input table (`signals`) each step of the staircase is
a time event, so its Model Exchange solver (`simulate`: CVode or Euler) integrates between
the steps with the inputs constant, as a Co-Simulation step holds them; `co_simulate` steps
the FMU through the same staircase with a communication step that divides its intervals.
Then the two differ only by their integrators' errors, which `simulate` at two tolerances or
steps measures. `ledger` sums a result's energy ledger (`Registration.ledger`), constant in
the exact solution. `ModelExchangeFMU` makes the calls of its FMU's FMI version through
FMPy's plumbing of that version (`harness.fmu.loader.VERSIONS`).
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Iterator, Mapping
from ctypes import POINTER, c_double
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException

from harness import registry
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU, FMUCallError, LogMessage, close_after, keeper, plumbing
from harness.scenarios import Scenario

MODEL_EXCHANGE = "ModelExchange"


def efforts(run: Any, scenario: Scenario) -> dict[str, np.ndarray]:
    """Each joint's effort over a co-simulation run (a RunResult) of the scenario [N m or
    N], at its recorded times (the effort held over the step that starts there), by input
    name."""
    joints = scenario.for_variant(scenario.variant(run.variant)).joints
    return {joint.effort: run.series[joint.effort].to_numpy(float) for joint in joints}


def staircase(scenario: Scenario, variant: str, times: np.ndarray,
              joint_efforts: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The inputs held over each interval [times[j], times[j+1]): the efforts given at
    times[j] and the variant's scenario inputs there, by name."""
    chosen = scenario.variant(variant)
    return {**joint_efforts, **scenario.for_variant(chosen).inputs(times, chosen)}


def signals(times: np.ndarray, held: dict[str, np.ndarray]) -> np.ndarray:
    """FMPy's input table of the staircase `held` (values held from each of times to the
    next): two rows per time but the first and last, the value before and the value after,
    so that every step is a time event and nothing is interpolated between them."""
    interior = np.arange(1, len(times) - 1)
    rows = np.concatenate([[0], np.repeat(interior, 2), [len(times) - 1]])
    # the value held up to each row's time, then (second of a pair) the one held from it
    held_at = np.concatenate([[0], np.column_stack([interior - 1, interior]).ravel(),
                              [len(times) - 2]])
    table = np.zeros(len(rows), dtype=[("time", np.float64)] + [
        (name, np.bool_ if values.dtype == bool else np.float64) for name, values in held.items()])
    table["time"] = times[rows]
    for name, values in held.items():
        table[name] = values[held_at]
    return table


def simulate(model: str, parameters: dict[str, Any], table: np.ndarray | None,
             stop_time: float, solver: str = "CVode", step_size: float = 1e-3,
             relative_tolerance: float = 1e-8, output: list[str] | None = None,
             output_interval: float = 0.01) -> np.ndarray:
    """The model's FMU (`harness.fmu.build.locate`) run as Model Exchange by FMPy from 0 to
    stop_time [s] with the parameters and the input table: CVode at the relative tolerance
    (outputs every output_interval [s]) or Euler at step_size [s] (FMPy takes one Euler step
    per output interval: outputs at every step). At an event the outputs just before it
    (as a Co-Simulation step that ends there reports them), not those after."""
    options: dict[str, Any] = {"solver": solver}
    if solver == "CVode":
        options.update(relative_tolerance=relative_tolerance, output_interval=output_interval)
    else:
        options.update(step_size=step_size, output_interval=step_size)
    result = simulate_fmu(str(fmu_build.locate(model)), fmi_type=MODEL_EXCHANGE,
                          start_values=parameters, input=table, stop_time=stop_time,
                          output=output, validate=True, record_events=True, **options)
    _, first = np.unique(result["time"], return_index=True)   # FMPy records before the event
    return result[np.sort(first)]


def co_simulate(model: str, parameters: dict[str, Any], times: np.ndarray,
                held: dict[str, np.ndarray], substeps: int, output: list[str]
                ) -> dict[str, np.ndarray]:
    """The model's FMU stepped as Co-Simulation through the staircase `held` (see
    `staircase`), each interval of times in `substeps` equal communication steps; the
    output variables at each of times."""
    rows = [dict.fromkeys(output, 0.0) for _ in times]
    with CoSimFMU(fmu_build.locate(model), f"{model}.staircase") as fmu:
        fmu.set({name: values[0] for name, values in held.items()})
        fmu.initialize(parameters, stop_time=float(times[-1]))
        rows[0] = fmu.get(output)
        for j in range(len(times) - 1):
            fmu.set({name: values[j] for name, values in held.items()})
            t, h = float(times[j]), (float(times[j + 1]) - float(times[j])) / substeps
            for k in range(substeps):
                fmu.step(t + k * h, h)
            rows[j + 1] = fmu.get(output)
    return {name: np.array([row[name] for row in rows], dtype=float) for name in output}


def ledger(model: str, result: Any) -> np.ndarray:
    """The signed sum of the model's energy ledger over a result [J] (`Registration.ledger`):
    constant in the exact solution."""
    terms = registry.registration(model).ledger
    return sum(sign * np.asarray(result[name], dtype=float) for name, sign in terms.items())


class ModelExchangeFMU:
    """One Model Exchange instance of a mechanism FMU for a host's own solver (the harness's
    Model Exchange engine): initialise it, book the event inputs' changes in event mode
    (`event`), then evaluate its derivatives and event indicators at the solver's times and
    states and read its outputs there. Every call's failure raises FMUCallError with the
    FMU's messages."""

    def __init__(self, path: str | Path, instance_name: str = "me") -> None:
        self.path = Path(path)
        self.model_description = read_model_description(str(self.path))
        self.fmi = plumbing(self.model_description)  # FMPy's plumbing of its FMI version
        self._unzip_dir = extract(str(self.path))
        self.variables = {v.name: v for v in self.model_description.modelVariables}
        self.messages: list[LogMessage] = []
        self._callbacks = self.fmi.callbacks(keeper(self.messages))
        self.model = self.fmi.model_exchange(self.model_description, self._unzip_dir,
                                             instance_name, self._callbacks)
        self.nx = self.model_description.numberOfContinuousStates
        self.nz = self.model_description.numberOfEventIndicators
        self._x, self._dx, self._z = np.zeros(self.nx), np.zeros(self.nx), np.zeros(self.nz)

    @contextlib.contextmanager
    def _calls(self) -> Iterator[None]:
        logged = len(self.messages)
        try:
            yield
        except FMICallException as error:
            raise FMUCallError(error, self.model_description.modelName,
                               self.messages[logged:]) from None

    def _set(self, values: Mapping[str, float | bool]) -> None:
        fmi = self.fmi
        for kind, convert in ((fmi.REAL, float), (fmi.BOOLEAN, bool)):
            chosen = {n: v for n, v in values.items() if self.variables[n].type == kind}
            if chosen:
                getattr(self.model, fmi.SETTERS[kind])(
                    [self.variables[n].valueReference for n in chosen],
                    [convert(v) for v in chosen.values()])

    def initialize(self, parameters: Mapping[str, float | bool],
                   inputs: Mapping[str, float | bool], stop_time: float) -> np.ndarray:
        """Set up, initialise with the parameters and inputs, settle the initial event and
        enter continuous-time mode; the continuous states."""
        with self._calls():
            self.fmi.initialize(self.model, 0.0, stop_time, lambda: self._set(parameters),
                                lambda: self._set(inputs))
            self._settle()
            self.model.enterContinuousTimeMode()
        return self.states()

    def _settle(self) -> None:
        """Update the discrete states until the event needs no more iterations."""
        while self.fmi.update_discrete_states(self.model):
            pass

    def event(self, time: float, x: np.ndarray, inputs: Mapping[str, float | bool]
              ) -> np.ndarray:
        """An event at time [s] with the states x: the inputs (discrete ones too) set in
        event mode, the event settled; the continuous states after it."""
        with self._calls():
            self.model.setTime(time)
            self._set_states(x)
            self.model.enterEventMode()
            self._set(inputs)
            self._settle()
            self.model.enterContinuousTimeMode()
        return self.states()

    def _set_states(self, x: np.ndarray) -> None:
        self._x[:] = x
        self.model.setContinuousStates(self._x.ctypes.data_as(POINTER(c_double)), self.nx)

    def states(self) -> np.ndarray:
        """The continuous states."""
        with self._calls():
            self.model.getContinuousStates(self._x.ctypes.data_as(POINTER(c_double)), self.nx)
        return self._x.copy()

    def evaluate(self, time: float, x: np.ndarray, inputs: Mapping[str, float]) -> None:
        """Make (time, x) and the continuous inputs the FMU's current point."""
        with self._calls():
            self.model.setTime(time)
            self._set_states(x)
            self._set(inputs)

    def derivatives(self) -> np.ndarray:
        """The state derivatives at the current point (`evaluate`)."""
        with self._calls():
            self.fmi.get_derivatives(self.model, self._dx.ctypes.data_as(POINTER(c_double)),
                                     self.nx)
        return self._dx.copy()

    def indicators(self) -> np.ndarray:
        """The event indicators at the current point (`evaluate`)."""
        with self._calls():
            self.model.getEventIndicators(self._z.ctypes.data_as(POINTER(c_double)), self.nz)
        return self._z.copy()

    def completed_step(self) -> bool:
        """The completed integrator step at the current point: True where the FMU asks for an
        event (its regime has changed without an indicator crossing)."""
        with self._calls():
            return self.model.completedIntegratorStep()[0]

    def get(self, names: list[str]) -> dict[str, float]:
        """Real and Boolean variables at the current point, by name."""
        fmi = self.fmi
        reals = [n for n in names if self.variables[n].type == fmi.REAL]
        bools = [n for n in names if self.variables[n].type == fmi.BOOLEAN]
        with self._calls():
            out = dict(zip(reals, getattr(self.model, fmi.GETTERS[fmi.REAL])(
                [self.variables[n].valueReference for n in reals])))
            out.update((n, float(v)) for n, v in zip(bools, getattr(
                self.model, fmi.GETTERS[fmi.BOOLEAN])(
                [self.variables[n].valueReference for n in bools])))
        return {n: out[n] for n in names}

    def close(self) -> None:
        """Terminate, free the instance and delete the extracted files."""
        try:
            with self._calls():
                self.model.terminate()
        finally:
            self.model.freeInstance()
            shutil.rmtree(self._unzip_dir, ignore_errors=True)

    def __enter__(self) -> ModelExchangeFMU:
        return self

    def __exit__(self, _type: type | None, error: BaseException | None, _trace: Any) -> None:
        close_after(self.close, error)
