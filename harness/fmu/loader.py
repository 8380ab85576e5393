"""Thin access to an FMI 2.0 Co-Simulation FMU through FMPy, by variable name.

`CoSimFMU` extracts an FMU once, instantiates it with a logger that keeps every message
(so tests and the harness can read warnings), and offers set/get by name, stepping,
state get/set and reset. The co-simulation master (`harness.run.master`) is built on it.
"""

from __future__ import annotations

import contextlib
import copyreg
import shutil
import zipfile
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    defaultCallbacks,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from harness.errors import UserError

__all__ = ["CoSimFMU", "FMICallException", "FMUCallError", "LogMessage"]

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
FATAL = STATUS_NAMES.index("Fatal")


@dataclass(frozen=True)
class LogMessage:
    """One message from the FMU logger."""

    status: str
    category: str
    message: str


class FMUCallError(FMICallException, UserError):
    """An FMI call the FMU refused, with the messages it logged: the FMU's own words (which
    name the variable) reach the user instead of only a status code."""

    def __init__(self, failure: FMICallException, model: str, messages: list[LogMessage]):
        super().__init__(failure.function, failure.status)
        # the model's Error messages; pythonfmu's own 'Fatal py exception' notes add nothing
        ours = [m.message for m in messages if m.status == "Error"] or [
            m.message for m in messages]
        self.messages = ours
        status = dict(enumerate(STATUS_NAMES)).get(failure.status, failure.status)
        self.args = (f"{model}: {failure.function} failed with status {status}"
                     + (f": {' | '.join(ours)}" if ours else ""),)

    def __reduce__(self) -> tuple:
        """Pickled as its message and attributes, as it comes back from a worker process
        (the default, cls(*args), does not fit __init__)."""
        return copyreg.__newobj__, (type(self), *self.args), self.__dict__


class CoSimFMU:
    """One instance of a Co-Simulation FMU, addressed by variable names."""

    def __init__(self, path: str | Path, instance_name: str = "instance") -> None:
        self.path = Path(path)
        try:
            self.model_description = read_model_description(str(self.path))
            self._unzip_dir = extract(str(self.path))
        except (zipfile.BadZipFile, OSError) as error:  # truncated or missing FMU
            raise UserError(f"{self.path}: not a readable FMU ({error}); rebuild it "
                            "(python -m harness build-fmus)") from None
        self.variables = {v.name: v for v in self.model_description.modelVariables}
        self._get_plans: dict[tuple[str, ...], tuple] = {}  # by the names `get` was given
        self.messages: list[LogMessage] = []
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self._callbacks.freeMemory = defaultCallbacks.freeMemory
        self.slave = FMU2Slave(guid=self.model_description.guid, unzipDirectory=self._unzip_dir,
                               modelIdentifier=self.model_description.coSimulation.modelIdentifier,
                               instanceName=instance_name)
        self.slave.instantiate(callbacks=self._callbacks, loggingOn=True)
        self.fatal = False  # after fmi2Fatal the standard allows no further call
        # where the messages of the run since the last initialize() begin; None before it
        self._run_start: int | None = None

    def _log(self, _env: Any, _instance: bytes, status: int, category: bytes,
             message: bytes) -> None:
        self.messages.append(LogMessage(STATUS_NAMES[status], (category or b"").decode(),
                                        (message or b"").decode()))

    def references(self, names: Iterable[str]) -> list[int]:
        """Value references of the named variables (KeyError names an unknown variable)."""
        try:
            return [self.variables[n].valueReference for n in names]
        except KeyError as error:
            raise KeyError(f"{self.path.name} has no variable {error.args[0]!r}") from None

    def set(self, values: Mapping[str, float | bool | str]) -> None:
        """Set Real, Boolean and String variables by name."""
        with self._watch_fatal():
            self._set(values)

    def _set(self, values: Mapping[str, float | bool | str]) -> None:
        reals = {n: v for n, v in values.items() if self.variables[n].type == "Real"}
        bools = {n: v for n, v in values.items() if self.variables[n].type == "Boolean"}
        strings = {n: v for n, v in values.items() if self.variables[n].type == "String"}
        unsupported = set(values) - set(reals) - set(bools) - set(strings)
        if unsupported:
            raise ValueError(f"{self.path.name}: cannot set {', '.join(sorted(unsupported))} "
                             "(only Real, Boolean and String variables)")
        if reals:
            self.slave.setReal(self.references(reals), [float(v) for v in reals.values()])
        if bools:
            self.slave.setBoolean(self.references(bools), [bool(v) for v in bools.values()])
        if strings:
            self.slave.setString(self.references(strings),
                                 [str(v) for v in strings.values()])

    def get(self, names: Iterable[str]) -> dict[str, float | bool | str]:
        """Current values of Real, Boolean and String variables by name."""
        names = tuple(names)
        plan = self._get_plans.get(names)
        if plan is None:
            plan = self._get_plans[names] = self._get_plan(names)
        reals, real_refs, bools, bool_refs, strings, string_refs = plan
        out: dict[str, float | bool | str] = {}
        if reals:
            out.update(zip(reals, self.slave.getReal(real_refs)))
        if bools:
            out.update((n, bool(v)) for n, v in zip(bools, self.slave.getBoolean(bool_refs)))
        if strings:
            out.update((n, v.decode() if isinstance(v, bytes) else v) for n, v in
                       zip(strings, self.slave.getString(string_refs)))
        return {n: out[n] for n in names}

    def _get_plan(self, names: tuple[str, ...]) -> tuple:
        """The names of each type among names and their value references, for `get` (made
        once per list of names: the master reads the same list at every recorded step)."""
        plan = []
        for kind in ("Real", "Boolean", "String"):
            chosen = [n for n in names if self.variables[n].type == kind]
            plan += [chosen, self.references(chosen)]
        return tuple(plan)

    def initialize(self, parameters: Mapping[str, float | bool] | None = None,
                   start_time: float = 0.0, stop_time: float | None = None) -> None:
        """setupExperiment, parameters, enter and exit initialisation mode."""
        with self._watch_fatal():
            self.slave.setupExperiment(startTime=start_time, stopTime=stop_time)
            self.slave.enterInitializationMode()
            if parameters:
                self._set(parameters)
            self.slave.exitInitializationMode()
        self._run_start = len(self.messages)

    def step(self, time: float, step_size: float) -> None:
        with self._watch_fatal():
            self.slave.doStep(currentCommunicationPoint=time, communicationStepSize=step_size)

    @contextlib.contextmanager
    def _watch_fatal(self) -> Iterator[None]:
        """Note a Fatal status, and raise a refused call as FMUCallError with its messages."""
        logged = len(self.messages)
        try:
            yield
        except FMICallException as error:
            self.fatal = self.fatal or error.status == FATAL
            raise FMUCallError(error, self.model_description.modelName,
                               self.messages[logged:]) from None

    def reset(self) -> None:
        self.slave.reset()
        self._run_start = None

    def _terminable(self) -> bool:
        """Whether fmi2Terminate may end the run: the instance was initialised and no call
        of the run failed since (FMI 2.0 allows fmi2Terminate only after a completed or
        refused step; after fmi2Error only a stored state or fmi2Reset goes on). A failed
        call, made here or straight through the FMU's functions, logs an Error message."""
        return (self._run_start is not None and not self.fatal and not any(
            m.status in ("Error", "Fatal") for m in self.messages[self._run_start:]))

    def names(self, causality: str) -> list[str]:
        """Names of the variables of one causality, in model-description order."""
        return [v.name for v in self.model_description.modelVariables
                if v.causality == causality]

    def close(self) -> None:
        """Terminate (when the run may be ended so, see `_terminable`), free the instance and
        delete the extracted files. A refused fmi2Terminate (the FMU could not end its run
        cleanly) raises FMUCallError with the FMU's messages once the instance is freed and
        the files deleted.

        After fmi2Fatal the instance is left alone: FMI 2.0 allows no further call, and
        pythonfmu 0.7.0 can crash the process if freeInstance follows a Fatal.
        """
        try:
            if self._terminable():
                with self._watch_fatal():
                    self.slave.terminate()
        finally:
            if not self.fatal:
                self.slave.freeInstance()
            shutil.rmtree(self._unzip_dir, ignore_errors=True)

    def __enter__(self) -> CoSimFMU:
        return self

    def __exit__(self, _type: type | None, error: BaseException | None, _trace: Any) -> None:
        """close(); when the block raised, a refused fmi2Terminate is a note on that error,
        which stays the one raised (it says what went wrong first)."""
        try:
            self.close()
        except FMUCallError as refused:
            if error is None:
                raise
            error.add_note(str(refused))
