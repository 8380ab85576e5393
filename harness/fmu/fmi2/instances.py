"""FMPy's FMI 2.0 instances, under the version-neutral facades of harness.fmu (`loader`,
`calls`, `model_exchange`): what differs between FMI versions in FMPy. That is the host's
callbacks, the instance classes, an experiment's set-up, the typed get and set methods, the
event update, the derivatives, and the C functions a fixed-step master calls on arrays. The
calls whose FMPy names every version shares (doStep, reset, terminate, freeInstance, setTime,
enterEventMode, getContinuousStates, ...) the facades make themselves.

Another FMI version's module offers the same names (`harness.fmu.loader.VERSIONS`).
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable
from typing import Any

from fmpy.fmi2 import (
    FMU2Model,
    FMU2Slave,
    defaultCallbacks,
    fmi2Boolean,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2False,
    fmi2ValueReference,
)
from fmpy.model_description import ModelDescription

VERSION = "2.0"  # the fmiVersion of the model descriptions served
# FMPy's types of variables (ModelVariable.type) and its methods that get and set them
REAL, BOOLEAN, STRING = "Real", "Boolean", "String"
GETTERS = {REAL: "getReal", BOOLEAN: "getBoolean", STRING: "getString"}
SETTERS = {REAL: "setReal", BOOLEAN: "setBoolean", STRING: "setString"}
# the C type of a Boolean value and its false, and the C functions of a master's step
C_BOOLEAN, C_FALSE = fmi2Boolean, fmi2False
GET_REAL, SET_REAL = "fmi2GetReal", "fmi2SetReal"
GET_BOOLEAN, SET_BOOLEAN = "fmi2GetBoolean", "fmi2SetBoolean"
DO_STEP = "fmi2DoStep"

# what the host's logger is given: the status, the category and the message (bytes or None)
Logger = Callable[[int, Any, Any], None]


def callbacks(log: Logger) -> fmi2CallbackFunctions:
    """The host's callbacks of an instance whose logger calls log (keep them as long as the
    instance lives)."""
    def logger(_env: Any, _instance: bytes, status: int, category: bytes,
               message: bytes) -> None:
        log(status, category, message)

    functions = fmi2CallbackFunctions()
    functions.logger = fmi2CallbackLoggerTYPE(logger)
    functions.allocateMemory = defaultCallbacks.allocateMemory
    functions.freeMemory = defaultCallbacks.freeMemory
    return functions


def co_simulation(md: ModelDescription, unzip_dir: str, instance_name: str,
                  functions: fmi2CallbackFunctions) -> FMU2Slave:
    """A Co-Simulation instance of the unzipped FMU, instantiated with logging on."""
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip_dir,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance_name)
    slave.instantiate(callbacks=functions, loggingOn=True)
    return slave


def model_exchange(md: ModelDescription, unzip_dir: str, instance_name: str,
                   functions: fmi2CallbackFunctions) -> FMU2Model:
    """A Model Exchange instance of the unzipped FMU, instantiated with logging on."""
    model = FMU2Model(guid=md.guid, unzipDirectory=unzip_dir, instanceName=instance_name,
                      modelIdentifier=md.modelExchange.modelIdentifier)
    model.instantiate(callbacks=functions, loggingOn=True)
    return model


def initialize(instance: FMU2Slave | FMU2Model, start_time: float, stop_time: float | None,
               set_parameters: Callable[[], None],
               set_inputs: Callable[[], None] | None = None) -> None:
    """Set up the experiment from start_time to stop_time [s] (None: open), set the inputs
    (set_inputs, before initialisation mode), enter initialisation mode, set the parameters
    (set_parameters) and exit it."""
    instance.setupExperiment(startTime=start_time, stopTime=stop_time)
    if set_inputs is not None:
        set_inputs()
    instance.enterInitializationMode()
    set_parameters()
    instance.exitInitializationMode()


def update_discrete_states(model: FMU2Model) -> bool:
    """One event iteration (fmi2NewDiscreteStates): whether the event needs another."""
    return model.newDiscreteStates()[0]


def get_derivatives(model: FMU2Model, derivatives: Any, nx: int) -> None:
    """The state derivatives into the C array derivatives (fmi2GetDerivatives)."""
    model.getDerivatives(derivatives, nx)


def references(values: list[int]) -> ctypes.Array:
    """Value references as a C array."""
    return (fmi2ValueReference * len(values))(*values)


def array_call(slave: FMU2Slave, function: str, refs: ctypes.Array,
               values: ctypes.Array) -> Callable[[], int]:
    """The instance's C function of that name (a get or set of one type, GET_REAL ...) bound
    to the C arrays of value references and values: called, it returns the status."""
    return functools.partial(getattr(slave.dll, function), slave.component, refs, len(refs),
                             values)


def step_call(slave: FMU2Slave) -> Callable[[float, float, bool], int]:
    """The instance's fmi2DoStep: (communication point, step size,
    noSetFMUStatePriorToCurrentPoint) -> status."""
    return functools.partial(slave.dll.fmi2DoStep, slave.component)
