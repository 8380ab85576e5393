"""Thin access to a Co-Simulation FMU through FMPy, by variable name.

`CoSimFMU` extracts an FMU once, instantiates it with a logger that keeps every message
(so tests and the harness can read warnings), and offers set/get by name, stepping,
state get/set and reset. The FMPy master (`harness.engines.fmpy_master`) is built on it.

What differs between FMI versions is FMPy's plumbing of the FMU's version (`VERSIONS`, by
the model description's fmiVersion: `harness.fmu.fmi2.instances` for FMI 2.0), which
`harness.fmu.calls` and `harness.fmu.model_exchange` use too.
"""

from __future__ import annotations

import contextlib
import copyreg
import shutil
import zipfile
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.model_description import ModelDescription

from harness.errors import UserError
from harness.fmu.fmi2 import instances as fmi2

__all__ = ["CoSimFMU", "FMICallException", "FMUCallError", "LogMessage"]

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
WARNING, FATAL = STATUS_NAMES.index("Warning"), STATUS_NAMES.index("Fatal")
# FMPy's plumbing of each FMI version, by the fmiVersion of the model description
VERSIONS: dict[str, ModuleType] = {fmi2.VERSION: fmi2}


@dataclass(frozen=True)
class LogMessage:
    """One message from the FMU logger."""

    status: str
    category: str
    message: str


def plumbing(md: ModelDescription) -> ModuleType:
    """FMPy's plumbing of the FMI version of the model description (`VERSIONS`); UserError
    for another version."""
    try:
        return VERSIONS[md.fmiVersion]
    except KeyError:
        raise UserError(f"{md.modelName}: FMI {md.fmiVersion} is not supported (only FMI "
                        f"{', '.join(VERSIONS)})") from None


def keeper(messages: list[LogMessage]) -> Callable[[int, Any, Any], None]:
    """A logger (`harness.fmu.fmi2.instances.Logger`) that keeps every message in
    messages."""
    def keep(status: int, category: bytes | None, message: bytes | None) -> None:
        messages.append(LogMessage(STATUS_NAMES[status], (category or b"").decode(),
                                   (message or b"").decode()))
    return keep


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
            self.fmi = plumbing(self.model_description)  # FMPy's plumbing of its version
            self._unzip_dir = extract(str(self.path))
        except (zipfile.BadZipFile, OSError) as error:  # truncated or missing FMU
            raise UserError(f"{self.path}: not a readable FMU ({error}); rebuild it "
                            "(python -m harness build-fmus)") from None
        self.variables = {v.name: v for v in self.model_description.modelVariables}
        self._get_plans: dict[tuple[str, ...], tuple] = {}  # by the names `get` was given
        self.messages: list[LogMessage] = []
        self._callbacks = self.fmi.callbacks(keeper(self.messages))
        self.slave = self.fmi.co_simulation(self.model_description, self._unzip_dir,
                                            instance_name, self._callbacks)
        self.fatal = False  # after a Fatal status the standard allows no further call
        # where the messages of the run since the last initialize() begin; None before it
        self._run_start: int | None = None

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
        fmi = self.fmi
        by_type = {kind: {n: v for n, v in values.items() if self.variables[n].type == kind}
                   for kind in (fmi.REAL, fmi.BOOLEAN, fmi.STRING)}
        unsupported = set(values).difference(*by_type.values())
        if unsupported:
            raise ValueError(f"{self.path.name}: cannot set {', '.join(sorted(unsupported))} "
                             "(only Real, Boolean and String variables)")
        for (kind, chosen), convert in zip(by_type.items(), (float, bool, str)):
            if chosen:
                getattr(self.slave, fmi.SETTERS[kind])(self.references(chosen),
                                                       [convert(v) for v in chosen.values()])

    def get(self, names: Iterable[str]) -> dict[str, float | bool | str]:
        """Current values of Real, Boolean and String variables by name."""
        names = tuple(names)
        plan = self._get_plans.get(names)
        if plan is None:
            plan = self._get_plans[names] = self._get_plan(names)
        reals, real_refs, bools, bool_refs, strings, string_refs = plan
        fmi, out = self.fmi, {}
        if reals:
            out.update(zip(reals, getattr(self.slave, fmi.GETTERS[fmi.REAL])(real_refs)))
        if bools:
            out.update((n, bool(v)) for n, v in zip(
                bools, getattr(self.slave, fmi.GETTERS[fmi.BOOLEAN])(bool_refs)))
        if strings:
            out.update((n, v.decode() if isinstance(v, bytes) else v) for n, v in zip(
                strings, getattr(self.slave, fmi.GETTERS[fmi.STRING])(string_refs)))
        return {n: out[n] for n in names}

    def _get_plan(self, names: tuple[str, ...]) -> tuple:
        """The names of each type among names and their value references, for `get` (made
        once per list of names: the master reads the same list at every recorded step)."""
        plan = []
        for kind in (self.fmi.REAL, self.fmi.BOOLEAN, self.fmi.STRING):
            chosen = [n for n in names if self.variables[n].type == kind]
            plan += [chosen, self.references(chosen)]
        return tuple(plan)

    def initialize(self, parameters: Mapping[str, float | bool] | None = None,
                   start_time: float = 0.0, stop_time: float | None = None) -> None:
        """Set up the experiment, enter initialisation mode, set the parameters, exit it."""
        with self._watch_fatal():
            self.fmi.initialize(self.slave, start_time, stop_time,
                                lambda: self._set(parameters) if parameters else None)
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
        """Whether terminate may end the run: the instance was initialised and no call of the
        run failed since (FMI 2.0 allows fmi2Terminate only after a completed or refused
        step; after fmi2Error only a stored state or fmi2Reset goes on). A failed call, made
        here or straight through the FMU's functions, logs an Error message."""
        return (self._run_start is not None and not self.fatal and not any(
            m.status in ("Error", "Fatal") for m in self.messages[self._run_start:]))

    def names(self, causality: str) -> list[str]:
        """Names of the variables of one causality, in model-description order."""
        return [v.name for v in self.model_description.modelVariables
                if v.causality == causality]

    def close(self) -> None:
        """Terminate (when the run may be ended so, see `_terminable`), free the instance and
        delete the extracted files. A refused terminate (the FMU could not end its run
        cleanly) raises FMUCallError with the FMU's messages once the instance is freed and
        the files deleted.

        After a Fatal status the instance is left alone: the standard allows no further call,
        and pythonfmu 0.7.0 can crash the process if freeInstance follows a Fatal.
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
        close_after(self.close, error)


def close_after(close: Callable[[], None], error: BaseException | None) -> None:
    """close() an instance at the end of its block; when the block raised error, a refused
    terminate is a note on that error, which stays the one raised (it says what went wrong
    first: the FMU's own message)."""
    try:
        close()
    except FMUCallError as refused:
        if error is None:
            raise
        error.add_note(str(refused))
