"""The FMI calls of a fixed-step master on one FMU instance (`MasterCalls`): the joints'
efforts set, the scenario's input changes applied, doStep, the joints' states read, and the
recorded variables read every recording interval, each on C arrays made once per run (FMPy's
wrappers build the arrays anew at each call), so that the master's loop makes one Python call
per step into this module and never touches the FMU's library itself. A refused call is an
`FMUCallError` with the FMU's own messages. The C functions are those of the FMU's FMI version
(`CoSimFMU.fmi`, `harness.fmu.fmi2.instances` for FMI 2.0)."""

from __future__ import annotations

import ctypes

import numpy as np
import pandas as pd

from harness.fmu.loader import FATAL, WARNING, CoSimFMU, FMICallException, FMUCallError


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
        fmi, slave = fmu.fmi, fmu.slave
        self.efforts = (ctypes.c_double * len(effort_names))()
        self.states = (ctypes.c_double * len(state_names))()
        self._set_efforts = fmi.array_call(slave, fmi.SET_REAL, self._references(effort_names),
                                           self.efforts)
        self._get_states = fmi.array_call(slave, fmi.GET_REAL, self._references(state_names),
                                          self.states)
        self._do_step = fmi.step_call(slave)
        self._changes = self._input_changes(inputs)
        kinds = {name: fmu.variables[name].type for name in record_names}
        self._record_names = record_names
        self._reals = [name for name in record_names if kinds[name] == "Real"]
        self._booleans = [name for name in record_names if kinds[name] == "Boolean"]
        self._others = [name for name in record_names if name not in self._reals + self._booleans]
        self._real_values = (ctypes.c_double * len(self._reals))()
        self._boolean_values = (fmi.C_BOOLEAN * len(self._booleans))()
        self._get_reals = fmi.array_call(slave, fmi.GET_REAL, self._references(self._reals),
                                         self._real_values)
        self._get_booleans = fmi.array_call(slave, fmi.GET_BOOLEAN,
                                            self._references(self._booleans),
                                            self._boolean_values)
        # each record() as the bytes of its C arrays, and the other types' values
        self._real_rows: list[bytes] = []
        self._boolean_rows: list[bytes] = []
        self._other_rows: list[list] = []

    def read_states(self) -> list[float]:
        """The joints' states now (FMUCallError if the FMU refuses)."""
        self._check(self._get_states(), self.fmu.fmi.GET_REAL)
        return self.states[:]

    def step(self, k: int, time: float, step_size: float) -> None:
        """Step k from time [s]: set the efforts, apply the inputs that change at k, doStep
        over step_size [s], read the joints' states (FMUCallError if the FMU refuses)."""
        if (status := self._set_efforts()) > WARNING:
            self._check(status, self.fmu.fmi.SET_REAL)
        if k in self._changes:
            for setter, value_array, value, function in self._changes[k]:
                value_array[0] = value
                self._check(setter(), function)
        # True: no FMU state is set back before the communication point
        if (status := self._do_step(time, step_size, True)) > WARNING:
            self._check(status, self.fmu.fmi.DO_STEP)
        if (status := self._get_states()) > WARNING:
            self._check(status, self.fmu.fmi.GET_REAL)

    def record(self) -> None:
        """Read the recorded variables' current values (FMUCallError if the FMU refuses)."""
        fmi = self.fmu.fmi
        self._check(self._get_reals(), fmi.GET_REAL)
        self._real_rows.append(bytes(self._real_values))
        if self._booleans:
            self._check(self._get_booleans(), fmi.GET_BOOLEAN)
            self._boolean_rows.append(bytes(self._boolean_values))
        if self._others:
            self._other_rows.append(list(self.fmu.get(self._others).values()))

    def recorded(self) -> pd.DataFrame:
        """One row per `record()`, one column per recorded variable."""
        rows, fmi = len(self._real_rows), self.fmu.fmi
        reals = np.frombuffer(b"".join(self._real_rows)).reshape(rows, len(self._reals))
        booleans = np.frombuffer(b"".join(self._boolean_rows), dtype=fmi.C_BOOLEAN).reshape(
            rows, len(self._booleans)) != fmi.C_FALSE
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
        if status <= WARNING:
            return
        self.fmu.fatal = self.fmu.fatal or status == FATAL
        raise FMUCallError(FMICallException(function, status), self.fmu.model_description.modelName,
                           self.fmu.messages[self.first_message:])

    def _references(self, names: list[str]) -> ctypes.Array:
        """The value references of the named variables as a C array."""
        return self.fmu.fmi.references(self.fmu.references(names))

    def _input_changes(self, inputs: dict[str, np.ndarray]) -> dict[int, list]:
        """Input changes by step index: {k: [(setter, C array, value, FMI function), ...]}:
        put the value in the array (of one element), then `setter()` sets the input from it
        through the FMI function that sets a Real or a Boolean and returns the status."""
        changes: dict[int, list] = {}
        fmi, slave = self.fmu.fmi, self.fmu.slave
        for name, signal in inputs.items():
            boolean = signal.dtype == bool
            function = fmi.SET_BOOLEAN if boolean else fmi.SET_REAL
            values = ((fmi.C_BOOLEAN if boolean else ctypes.c_double) * 1)()
            setter = fmi.array_call(slave, function, self._references([name]), values)
            steps = np.flatnonzero(signal[1:] != signal[:-1]) + 1
            for k, value in zip(steps.tolist(), signal[steps].tolist(), strict=True):
                changes.setdefault(k, []).append((setter, values, value, function))
        return changes
