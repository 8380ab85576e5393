"""The FMI calls of a fixed-step master on one FMU instance (`MasterCalls`): the joints'
efforts set, the scenario's input changes applied, doStep, the joints' states read, and the
recorded variables read every recording interval, each on C arrays made once per run (FMPy's
wrappers build the arrays anew at each call), so that the master's loop makes one Python call
per step into this module and never touches the FMU's library itself. A refused call is an
`FMUCallError` with the FMU's own messages."""

from __future__ import annotations

import ctypes
import functools

import numpy as np
import pandas as pd
from fmpy.fmi2 import fmi2Boolean, fmi2False, fmi2True, fmi2ValueReference, fmi2Warning

from harness.fmu.loader import FATAL, CoSimFMU, FMICallException, FMUCallError


class MasterCalls:
    """The calls of a master's step on an initialised FMU: `efforts` (one C double per joint,
    which the master fills before each step) are set, the input changes of the step applied,
    the FMU stepped and the joints' `states` (position and speed per joint, in state_names'
    order) read; `record()` reads the recorded variables and `recorded()` is the table of what
    it read.

    inputs: the scenario's input signals at every communication point (step k's values at
    index k); they are set only where they change, step 0's before initialisation by the
    caller. first_message: the index of the run's first message in fmu.messages, for the
    error of a refused call."""

    def __init__(self, fmu: CoSimFMU, effort_names: list[str], state_names: list[str],
                 record_names: list[str], inputs: dict[str, np.ndarray],
                 first_message: int) -> None:
        self.fmu, self.first_message = fmu, first_message
        dll, component = fmu.slave.dll, fmu.slave.component
        self.efforts = (ctypes.c_double * len(effort_names))()
        self.states = (ctypes.c_double * len(state_names))()
        self._set_efforts = functools.partial(dll.fmi2SetReal, component,
                                              self._references(effort_names),
                                              len(effort_names), self.efforts)
        self._get_states = functools.partial(dll.fmi2GetReal, component,
                                             self._references(state_names), len(state_names),
                                             self.states)
        self._do_step = functools.partial(dll.fmi2DoStep, component)
        self._changes = self._input_changes(inputs)
        kinds = {name: fmu.variables[name].type for name in record_names}
        self._record_names = record_names
        self._reals = [name for name in record_names if kinds[name] == "Real"]
        self._booleans = [name for name in record_names if kinds[name] == "Boolean"]
        self._others = [name for name in record_names if name not in self._reals + self._booleans]
        self._real_values = (ctypes.c_double * len(self._reals))()
        self._boolean_values = (fmi2Boolean * len(self._booleans))()
        self._get_reals = functools.partial(dll.fmi2GetReal, component,
                                            self._references(self._reals), len(self._reals),
                                            self._real_values)
        self._get_booleans = functools.partial(
            dll.fmi2GetBoolean, component, self._references(self._booleans),
            len(self._booleans), self._boolean_values)
        # each record() as the bytes of its C arrays, and the other types' values
        self._real_rows: list[bytes] = []
        self._boolean_rows: list[bytes] = []
        self._other_rows: list[list] = []

    def read_states(self) -> list[float]:
        """The joints' states now (FMUCallError if the FMU refuses)."""
        self._check(self._get_states(), "fmi2GetReal")
        return self.states[:]

    def step(self, k: int, time: float, step_size: float) -> None:
        """Step k from time [s]: set the efforts, apply the inputs that change at k, doStep
        over step_size [s], read the joints' states (FMUCallError if the FMU refuses)."""
        if (status := self._set_efforts()) > fmi2Warning:
            self._check(status, "fmi2SetReal")
        if k in self._changes:
            for setter, value_array, value, function in self._changes[k]:
                value_array[0] = value
                self._check(setter(), function)
        if (status := self._do_step(time, step_size, fmi2True)) > fmi2Warning:
            self._check(status, "fmi2DoStep")
        if (status := self._get_states()) > fmi2Warning:
            self._check(status, "fmi2GetReal")

    def record(self) -> None:
        """Read the recorded variables' current values (FMUCallError if the FMU refuses)."""
        self._check(self._get_reals(), "fmi2GetReal")
        self._real_rows.append(bytes(self._real_values))
        if self._booleans:
            self._check(self._get_booleans(), "fmi2GetBoolean")
            self._boolean_rows.append(bytes(self._boolean_values))
        if self._others:
            self._other_rows.append(list(self.fmu.get(self._others).values()))

    def recorded(self) -> pd.DataFrame:
        """One row per `record()`, one column per recorded variable."""
        rows = len(self._real_rows)
        reals = np.frombuffer(b"".join(self._real_rows)).reshape(rows, len(self._reals))
        booleans = np.frombuffer(b"".join(self._boolean_rows), dtype=fmi2Boolean).reshape(
            rows, len(self._booleans)) != fmi2False
        table = pd.concat([pd.DataFrame(reals, columns=self._reals),
                           pd.DataFrame(booleans, columns=self._booleans),
                           pd.DataFrame(self._other_rows, columns=self._others)], axis=1)
        return table[self._record_names]

    def messages(self) -> list[str]:
        """The messages the FMU logged since the run's first, as 'status: message'."""
        return [f"{m.status}: {m.message}" for m in self.fmu.messages[self.first_message:]]

    def _check(self, status: int, function: str) -> None:
        """FMUCallError with the messages the FMU logged since the run's first when status is
        above Warning (noting a Fatal status, after which the FMU is not called again)."""
        if status <= fmi2Warning:
            return
        self.fmu.fatal = self.fmu.fatal or status == FATAL
        raise FMUCallError(FMICallException(function, status), self.fmu.model_description.modelName,
                           self.fmu.messages[self.first_message:])

    def _references(self, names: list[str]) -> ctypes.Array:
        """The value references of the named variables as a C array."""
        references = self.fmu.references(names)
        return (fmi2ValueReference * len(references))(*references)

    def _input_changes(self, inputs: dict[str, np.ndarray]) -> dict[int, list]:
        """Input changes by step index: {k: [(setter, C array, value, FMI function), ...]}:
        put the value in the array (of one element), then `setter()` sets the input from it
        through fmi2SetReal or fmi2SetBoolean and returns the status."""
        changes: dict[int, list] = {}
        slave = self.fmu.slave
        for name, signal in inputs.items():
            boolean = signal.dtype == bool
            function = "fmi2SetBoolean" if boolean else "fmi2SetReal"
            values = ((fmi2Boolean if boolean else ctypes.c_double) * 1)()
            setter = functools.partial(getattr(slave.dll, function), slave.component,
                                       self._references([name]), 1, values)
            steps = np.flatnonzero(signal[1:] != signal[:-1]) + 1
            for k, value in zip(steps.tolist(), signal[steps].tolist(), strict=True):
                changes.setdefault(k, []).append((setter, values, value, function))
        return changes
