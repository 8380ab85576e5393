"""The master's per-step work, made once per run: each joint's PID and sampled motor fused in
one function per step (`DriveLoop`), and the FMU's fmi2SetReal, fmi2DoStep and fmi2GetReal on
C arrays (`FMICalls`, `input_changes`), so the loop does no per-step lookups."""

from __future__ import annotations

import ctypes
import functools

import numpy as np
import pandas as pd
from fmpy.fmi2 import fmi2Boolean, fmi2False, fmi2ValueReference, fmi2Warning

from fmu_src.units.controller.pid import DiscretePID
from harness.fmu.loader import FATAL, CoSimFMU, FMICallException, FMUCallError
from harness.run.drive import DriveTrace, MotorParameters, SampledMotor
from harness.run.scenario_files import Joint


class DriveLoop:
    """One joint's discrete PID and sampled motor in the master's loop, with a record of
    each step k: the joint's position and speed at its start (and at the end of the last
    step, which the master puts in), the voltage [V], the armature current at its start [A]
    (and at the end of the last step), its step average [A] and the effort [N m or N].

    `step` is the joint's step: `DiscretePID.update` and `SampledMotor.step` fused into one
    function over local variables (one Python call per joint and step instead of four), the
    same operations in the same order, so the same numbers to the last bit
    (tests/test_master_loop.py checks it against the two).
    """

    __slots__ = ("step", "position", "speed", "voltage", "start_current", "current", "effort")

    def __init__(self, pid: DiscretePID, motor: SampledMotor, reference: list[float],
                 efforts: ctypes.Array, index: int) -> None:
        """A drive for a run of len(reference) - 1 steps that puts its effort in
        efforts[index]; the PID's and motor's state then live in `step`."""
        n_steps = len(reference) - 1
        positions = self.position = [0.0] * (n_steps + 1)
        speeds = self.speed = [0.0] * (n_steps + 1)
        voltages, currents, effort_record = [0.0] * n_steps, [0.0] * n_steps, [0.0] * n_steps
        starts = [motor.current] + [0.0] * n_steps
        self.voltage, self.start_current = voltages, starts
        self.current, self.effort = currents, effort_record
        b0, b1, a1, half_ki_dt = pid.coefficients
        gain, limit = pid.gains.Kp, pid.limit
        integral, previous, derivative = pid.state()[:3]
        a, b_v, b_w, avg_a, avg_b_v, avg_b_w = motor.coefficients
        torque_per_amp, current = motor.motor.torque_per_amp, motor.current

        def step(k: int, position: float, speed: float) -> None:
            """Step k from the joint's position and speed at its start: puts the effort over
            it in efforts[index] and records the step."""
            nonlocal integral, previous, derivative, current
            # DiscretePID.update
            error = reference[k] - position
            derivative = -a1 * derivative + b0 * error + b1 * previous
            candidate = integral + half_ki_dt * (error + previous)
            unclamped = gain * error + candidate + derivative
            voltage = limit if unclamped > limit else -limit if unclamped < -limit else unclamped
            if voltage == unclamped or (unclamped > 0) != (error > 0):
                integral = candidate
            previous = error
            # SampledMotor.step
            average = avg_a * current + avg_b_v * voltage + avg_b_w * speed
            current = a * current + b_v * voltage + b_w * speed
            efforts[index] = effort_record[k] = torque_per_amp * average
            voltages[k], currents[k], starts[k + 1] = voltage, average, current
            positions[k], speeds[k] = position, speed

        self.step = step

    def trace(self, joint: Joint, motor: MotorParameters, step_size: float,
              reference: np.ndarray) -> DriveTrace:
        """The drive's trace of the run."""
        return DriveTrace(joint, motor, step_size, np.array(self.voltage),
                          np.array(self.current), np.array(self.effort),
                          np.array(self.start_current), np.array(self.position),
                          np.array(self.speed), reference)


class FMICalls:
    """The loop's FMI calls on ctypes arrays made once: set the joints' efforts, doStep and
    get the joints' states call the FMU's C functions directly and return their status
    (FMPy's wrappers build the arrays anew at each call); `record()` reads the recorded
    variables the same way (one fmi2GetReal, and one fmi2GetBoolean if some are Boolean)
    and `recorded()` is the table of what it read. first_message: the index of the run's
    first message in fmu.messages, for the error of a refused read."""

    def __init__(self, fmu: CoSimFMU, input_names: list[str], state_names: list[str],
                 record_names: list[str], first_message: int) -> None:
        slave = fmu.slave
        component, dll = slave.component, slave.dll
        self.inputs = (ctypes.c_double * len(input_names))()
        self.states = (ctypes.c_double * len(state_names))()
        self.set_inputs = functools.partial(dll.fmi2SetReal, component,
                                            _references(fmu, input_names), len(input_names),
                                            self.inputs)
        self.get_states = functools.partial(dll.fmi2GetReal, component,
                                            _references(fmu, state_names), len(state_names),
                                            self.states)
        self.do_step = functools.partial(dll.fmi2DoStep, component)
        kinds = {name: fmu.variables[name].type for name in record_names}
        self._record_names = record_names
        self._reals = [name for name in record_names if kinds[name] == "Real"]
        self._booleans = [name for name in record_names if kinds[name] == "Boolean"]
        self._others = [name for name in record_names if name not in self._reals + self._booleans]
        self._real_values = (ctypes.c_double * len(self._reals))()
        self._boolean_values = (fmi2Boolean * len(self._booleans))()
        self._get_reals = functools.partial(dll.fmi2GetReal, component,
                                            _references(fmu, self._reals), len(self._reals),
                                            self._real_values)
        self._get_booleans = functools.partial(
            dll.fmi2GetBoolean, component, _references(fmu, self._booleans),
            len(self._booleans), self._boolean_values)
        self._fmu, self._first_message = fmu, first_message
        # each record() as the bytes of its C arrays, and the other types' values
        self._real_rows: list[bytes] = []
        self._boolean_rows: list[bytes] = []
        self._other_rows: list[list] = []

    def record(self) -> None:
        """Read the recorded variables' current values (FMUCallError if the FMU refuses)."""
        if (status := self._get_reals()) > fmi2Warning:
            raise refused(self._fmu, "fmi2GetReal", status, self._first_message)
        self._real_rows.append(bytes(self._real_values))
        if self._booleans:
            if (status := self._get_booleans()) > fmi2Warning:
                raise refused(self._fmu, "fmi2GetBoolean", status, self._first_message)
            self._boolean_rows.append(bytes(self._boolean_values))
        if self._others:
            self._other_rows.append(list(self._fmu.get(self._others).values()))

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


def refused(fmu: CoSimFMU, function: str, status: int, first_message: int) -> FMUCallError:
    """The error of an FMI call the FMU refused, with the messages it logged since the run's
    first (noting a Fatal status, after which the FMU is not called again)."""
    fmu.fatal = fmu.fatal or status == FATAL
    return FMUCallError(FMICallException(function, status), fmu.model_description.modelName,
                        fmu.messages[first_message:])


def _references(fmu: CoSimFMU, names: list[str]) -> ctypes.Array:
    """The value references of the named variables as a C array."""
    references = fmu.references(names)
    return (fmi2ValueReference * len(references))(*references)


def input_changes(fmu: CoSimFMU, inputs: dict[str, np.ndarray]) -> dict[int, list]:
    """Input changes by step index: {k: [(setter, C array, value, FMI function), ...]}: put
    the value in the array (of one element), then `setter()` sets the input from it through
    the FMU's fmi2SetReal or fmi2SetBoolean and returns the status.

    Inputs are set only at the communication points where they change (step 0's values are
    set before initialisation), which keeps the loop free of per-input work.
    """
    changes: dict[int, list] = {}
    slave = fmu.slave
    for name, signal in inputs.items():
        boolean = signal.dtype == bool
        function = "fmi2SetBoolean" if boolean else "fmi2SetReal"
        values = ((fmi2Boolean if boolean else ctypes.c_double) * 1)()
        setter = functools.partial(getattr(slave.dll, function), slave.component,
                                   _references(fmu, [name]), 1, values)
        steps = np.flatnonzero(signal[1:] != signal[:-1]) + 1
        for k, value in zip(steps.tolist(), signal[steps].tolist(), strict=True):
            changes.setdefault(k, []).append((setter, values, value, function))
    return changes
