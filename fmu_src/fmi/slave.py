"""Shared pythonfmu base class for the FMUs of this project (standard library only).

`ModelSlave` is a thin FMI layer over a pure model module: the mechanisms, the DC motor
drive and the position controller all use it. `MechanismSlave` adds the step, event and
state plumbing every mechanism shares, from the physics module's common functions.

PythonFMU 0.7.0 writes no units, no min/max, no TypeDefinitions and no InitialUnknowns
(its issue #33). `ModelSlave.to_xml` adds them, in the way DNV's component-model does,
from one table of variable metadata that is also used to check inputs at run time. It also
writes each output's `dependencies`, from the inputs `add_output` declares it depends on.

Outputs are up to date whenever they are read: in a slave whose outputs are functions of
its state and inputs (`refresh_outputs`), an output read after an input was set is recomputed
first, so a host sees a changed payload in tau_gravity at once, not one step later. Outputs
declared independent of the inputs then read the same, which the tests check input by input.

Error reporting: a refusal that ends the call is a ValueError whose message names the
variable and its range; the FMU's runtime (harness/fmu/runtime/fmi2_runtime.c on Linux) returns
fmi2Error and logs "<fmi2 function>: ValueError: <message>" (pythonfmu's win64 binary returns
fmi2Fatal with the same message). So a bad parameter fails fmi2ExitInitializationMode, and a
Real input set NaN, infinite or outside its range, a fixed parameter set after
initialisation, or an output set at all fails fmi2SetReal (fmi2SetBoolean, fmi2SetString),
and the value stays. A bad step size fails fmi2DoStep with fmi2Discard (do_step returns
False) after an Error-status log message.

A refused step leaves the instance as it was before the call: `do_step` refuses a step
whose work would exceed the integrator's bound (`fmu_src.integration.MAX_SUBSTEPS`), that
the physics refuses (`fmu_src.parameters.DomainError`), whose arithmetic fails, or whose
outputs would not be finite, and restores the state. Any other exception of a step is a
defect: it propagates (fmi2Error, naming its type). A restored FMU state must be one of this
model and layout, of the right types, and is validated like a fresh initialisation; a
refused one changes nothing.
"""

from __future__ import annotations

import builtins
import contextlib
import hashlib
import math
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from functools import cached_property, partial
from operator import attrgetter, itemgetter
from typing import Any
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import ScalarVariable

from fmu_src.parameters import MAGNITUDE_LIMIT, DomainError, check_ranges, magnitude_problem

SMALLEST = 1.0 / MAGNITUDE_LIMIT  # the smallest non-zero magnitude of an input

# ValueError texts of the math module: a failed computation, not a message of ours.
MATH_ERRORS = ("math domain error", "math range error")
# keys of an FMU state besides its variables' names
STATE_MODEL, STATE_LAYOUT, STATE_HIDDEN = "__model__", "__layout__", "__hidden__"
# the Python types a variable's value in an FMU state may have, by its FMI type
STATE_TYPES = {Real: (float, int), Boolean: (bool,), Integer: (int,), String: (str,)}

# unit -> (quantity used as the declared type name, SI base-unit exponents)
UNITS: dict[str, tuple[str, dict[str, int]]] = {
    "1": ("Dimensionless", {}),
    "s": ("Time", {"s": 1}),
    "m": ("Length", {"m": 1}),
    "m/s": ("Velocity", {"m": 1, "s": -1}),
    "m/s2": ("Acceleration", {"m": 1, "s": -2}),
    "rad": ("Angle", {"rad": 1}),
    "rad/s": ("AngularVelocity", {"rad": 1, "s": -1}),
    "kg": ("Mass", {"kg": 1}),
    "kg.m2": ("MomentOfInertia", {"kg": 1, "m": 2}),
    "N": ("Force", {"kg": 1, "m": 1, "s": -2}),
    "N.m": ("Torque", {"kg": 1, "m": 2, "s": -2}),
    "J": ("Energy", {"kg": 1, "m": 2, "s": -2}),
    "W": ("Power", {"kg": 1, "m": 2, "s": -3}),
    "N/m": ("TranslationalSpringConstant", {"kg": 1, "s": -2}),
    "N.s/m": ("TranslationalDampingConstant", {"kg": 1, "s": -1}),
    "N.m.s/rad": ("RotationalDampingConstant", {"kg": 1, "m": 2, "s": -1, "rad": -1}),
    "V": ("Voltage", {"kg": 1, "m": 2, "s": -3, "A": -1}),
    "A": ("Current", {"A": 1}),
    "Ohm": ("Resistance", {"kg": 1, "m": 2, "s": -3, "A": -2}),
    "H": ("Inductance", {"kg": 1, "m": 2, "s": -2, "A": -2}),
    "N.m/A": ("TorqueConstant", {"kg": 1, "m": 2, "s": -2, "A": -1}),
    "V/rad": ("VoltagePerAngle", {"kg": 1, "m": 2, "s": -3, "A": -1, "rad": -1}),
    "V/(rad.s)": ("VoltagePerAngleTime", {"kg": 1, "m": 2, "s": -4, "A": -1, "rad": -1}),
    "V.s/rad": ("VoltagePerAngularVelocity", {"kg": 1, "m": 2, "s": -2, "A": -1, "rad": -1}),
}
# display units: unit -> (display unit, factor): display = factor * value
DISPLAY_UNITS = {"rad": ("deg", 180.0 / math.pi), "rad/s": ("deg/s", 180.0 / math.pi)}


@dataclass(frozen=True)
class VariableInfo:
    """Model-description metadata of one variable."""

    unit: str | None
    description: str
    min: float | None = None
    max: float | None = None


class ModelSlave(Fmi2Slave):
    """Base of the slaves: a thin FMI layer over a pure model module.

    Subclasses set `parameters_type` (a frozen dataclass whose fields come from
    `fmu_src.parameters.parameter`; bool fields become Boolean parameters, the others Real
    parameters), register inputs and outputs with `add_input`/`add_output`, and implement
    `initialise(params)` and `step(dt)`; `validate(params)` checks the field ranges unless
    overridden. Their hidden state is listed in `hidden_state`. A subclass whose outputs are
    functions of its state and inputs implements `refresh_outputs` and keeps its outputs in
    `output_values` (a tuple in output_names order, replaced at once by `set_outputs`); the
    others keep each output in the attribute of its name.
    """

    parameters_type: type
    hidden_state: tuple[str, ...] = ()

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        # pythonfmu's runtime puts the resources folder (where it reads slavemodule.txt)
        # first on sys.path at every instantiation, to import the slave module, and never
        # takes it out: one entry per instance, pointing at folders hosts delete. The module
        # is imported by now. (pythonfmu's builder removes its own entry itself.)
        if self.resources in sys.path and os.path.exists(
                os.path.join(self.resources, "slavemodule.txt")):
            with contextlib.suppress(ValueError):  # another thread's instance took it out
                sys.path.remove(self.resources)
        self.author = "Gravity balancer co-simulation project"
        self.license = "MIT"
        self.info: dict[str, VariableInfo] = {}
        # (name, lowest, highest) per Real input within +-MAGNITUDE_LIMIT, so one chained
        # comparison per input also rejects NaN, +-inf and huge values.
        self.real_input_bounds: list[tuple[str, float, float]] = []
        # per output, the inputs it depends on at communication points and in initialisation
        self.dependencies: dict[str, tuple[str, ...]] = {}
        self.initial_dependencies: dict[str, tuple[str, ...]] = {}
        # an input was set since the outputs were computed (always, in a slave that does
        # not refresh them: get_real then reads each output's own getter)
        self.outputs_stale = not self.refreshes_outputs
        self.params = None
        self.start_time = 0.0
        self.real_outputs: list[str] = []  # names of the Real outputs, checked finite per step
        self.calculated: list[str] = []    # names of the calculated parameters
        self.output_names: list[str] = []  # names of all outputs, restored by a refused step
        self.output_values: tuple = ()     # the outputs of a slave that refreshes them
        for f in fields(self.parameters_type):
            meta = f.metadata
            setattr(self, f.name, f.default)
            if isinstance(f.default, bool):
                self._add(Boolean(f.name, causality=Fmi2Causality.parameter,
                                  variability=Fmi2Variability.fixed,
                                  description=meta["description"]),
                          VariableInfo(None, meta["description"]))
            else:
                self._add(Real(f.name, causality=Fmi2Causality.parameter,
                               variability=Fmi2Variability.fixed,
                               description=meta["description"]),
                          VariableInfo(meta["unit"], meta["description"], meta["min"],
                                       meta["max"]))

    # ---- registration -------------------------------------------------------------
    def _add(self, var: Real | Boolean, info: VariableInfo) -> None:
        self.info[var.name] = info
        self.register_variable(var)
        if var.causality in (Fmi2Causality.parameter, Fmi2Causality.calculatedParameter):
            var.setter = self._parameter_setter(var.name, var.causality)
        for table in ("_real_getters", "_real_setters", "_output_positions"):  # built again
            self.__dict__.pop(table, None)

    def _parameter_setter(self, name: str, causality: Fmi2Causality) -> Any:
        """Setter of a fixed or calculated parameter: refused once initialised (the model
        would not use the new value) and always for a calculated one."""
        def set_parameter(value: Any) -> None:
            if causality == Fmi2Causality.calculatedParameter:
                problem = f"{name} is a calculated parameter: it cannot be set"
            elif self.params is not None:
                problem = (f"{name} is a fixed parameter: it cannot be set after "
                           "initialisation (set it before fmi2ExitInitializationMode)")
            else:
                setattr(self, name, value)
                return
            raise ValueError(problem)
        return set_parameter

    def add_calculated_parameter(self, name: str, unit: str, description: str) -> None:
        """A parameter derived from the others at initialisation."""
        setattr(self, name, 0.0)
        self.calculated.append(name)
        self._add(Real(name, causality=Fmi2Causality.calculatedParameter,
                       variability=Fmi2Variability.fixed, initial=Fmi2Initial.calculated,
                       description=description), VariableInfo(unit, description))

    def add_input(self, name: str, start: float | bool, unit: str | None, description: str,
                  min: float | None = None, max: float | None = None) -> None:
        """A Real (unit given) or Boolean (unit None) input held over a communication step."""
        setattr(self, name, start)
        if unit is None:
            var = Boolean(name, causality=Fmi2Causality.input,
                          variability=Fmi2Variability.discrete, description=description)
        else:
            var = Real(name, causality=Fmi2Causality.input,
                       variability=Fmi2Variability.continuous, description=description)
            self.real_input_bounds.append((
                name, -MAGNITUDE_LIMIT if min is None else builtins.max(min, -MAGNITUDE_LIMIT),
                MAGNITUDE_LIMIT if max is None else builtins.min(max, MAGNITUDE_LIMIT)))
        self._add(var, VariableInfo(unit, description, min, max))

    def add_output(self, name: str, unit: str | None, description: str,
                   depends_on: tuple[str, ...] = (),
                   initial_depends_on: tuple[str, ...] | None = None) -> None:
        """A Real (unit given) or Boolean (unit None) output computed by the model.

        depends_on: the inputs whose current values the output depends on at a communication
        point (its ModelStructure dependencies); empty for a function of the state alone.
        initial_depends_on: the inputs it depends on at initialisation, where they differ (an
        output of the last step, computed at the start from the inputs then).
        """
        inputs = {var.name: var for var in self.vars.values()
                  if var.causality == Fmi2Causality.input}
        unknown = [n for n in (*depends_on, *(initial_depends_on or ())) if n not in inputs]
        if unknown:
            raise ValueError(f"output {name} depends on {', '.join(unknown)}, which are not "
                             "inputs registered before it")
        if depends_on and not self.refreshes_outputs:
            raise TypeError(f"{type(self).__name__}.{name} depends on inputs: implement "
                            "refresh_outputs")
        self.dependencies[name] = tuple(depends_on)
        self.initial_dependencies[name] = tuple(
            depends_on if initial_depends_on is None else initial_depends_on)
        start = False if unit is None else 0.0
        if self.refreshes_outputs:
            self.output_values = (*self.output_values, start)
        else:
            setattr(self, name, start)
        self.output_names.append(name)
        if unit is None:
            var = Boolean(name, causality=Fmi2Causality.output,
                          variability=Fmi2Variability.discrete, initial=Fmi2Initial.calculated,
                          description=description)
        else:
            var = Real(name, causality=Fmi2Causality.output,
                       variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated,
                       description=description)
            self.real_outputs.append(name)
        self._add(var, VariableInfo(unit, description))

    @property
    def refreshes_outputs(self) -> bool:
        """The slave recomputes its outputs when read after an input was set."""
        return type(self).refresh_outputs is not ModelSlave.refresh_outputs

    def register_variable(self, var: ScalarVariable, nested: bool = True) -> None:
        """pythonfmu's registration, with inputs checked when set, which make the outputs
        stale; where the slave refreshes its outputs, outputs recomputed when read stale;
        and outputs (any variable but an input or a parameter) that refuse to be set."""
        super().register_variable(var, nested)
        if var.causality == Fmi2Causality.input:
            var.setter = self._input_setter(var.name)
        elif var.causality not in (Fmi2Causality.parameter, Fmi2Causality.calculatedParameter):
            var.setter = _refused_setter(var.name, var.causality.name)
            if var.causality == Fmi2Causality.output and self.refreshes_outputs:
                var.getter = self._output_getter(var.name)

    # Closures over the instance's __dict__: they run at every fmi2Get/fmi2Set call.
    def _input_setter(self, name: str) -> Callable[[Any], None]:
        """Setter of an input: the outputs become stale; a Real input NaN, infinite, outside
        its range or its magnitudes is refused (a ValueError naming it and its range) and
        keeps its value."""
        attributes = self.__dict__
        bounds = [(low, high) for n, low, high in self.real_input_bounds if n == name]
        if not bounds:
            def set_input(value: Any) -> None:
                attributes[name] = value
                attributes["outputs_stale"] = True
            return set_input
        lowest, highest = bounds[0]

        def set_real_input(value: Any) -> None:
            # _input_problem's tests in one chained comparison (also false for NaN)
            if not (lowest <= value <= highest
                    and (value == 0.0 or not -SMALLEST < value < SMALLEST)):
                raise ValueError(self._input_problem(name, value))
            attributes[name] = value
            attributes["outputs_stale"] = True
        return set_real_input

    def _output_getter(self, name: str) -> Callable[[], Any]:
        """Getter of an output of a refreshing slave: all are recomputed first if an input was
        set since they were (before initialisation there is nothing to compute them from)."""
        attributes = self.__dict__
        index = self.output_names.index(name)

        def current_output() -> Any:
            if attributes["outputs_stale"]:
                attributes["outputs_stale"] = False
                if self.params is not None:
                    self.refresh_outputs()
            return attributes["output_values"][index]
        return current_output

    # fmi2GetReal/fmi2SetReal: pythonfmu's look each variable up and check its type per call
    @cached_property
    def _real_getters(self) -> dict[int, Callable[[], Any]]:
        """Getter of each Real variable by value reference (complete once registered)."""
        return {vr: var.getter for vr, var in self.vars.items() if isinstance(var, Real)}

    @cached_property
    def _real_setters(self) -> dict[int, Callable[[Any], None]]:
        """Setter of each Real variable by value reference."""
        return {vr: var.setter for vr, var in self.vars.items() if isinstance(var, Real)}

    @cached_property
    def _output_positions(self) -> dict[int, int]:
        """Position in output_values of each Real output by value reference."""
        return {vr: self.output_names.index(var.name) for vr, var in self.vars.items()
                if var.name in self.real_outputs}

    def get_real(self, vrs: list[int]) -> list[float]:
        if not self.outputs_stale:  # current outputs of a refreshing slave: read at once
            positions, values = self._output_positions, self.output_values
            try:
                return [values[positions[vr]] for vr in vrs]
            except KeyError:  # not only outputs
                pass
        getters = self._real_getters
        try:
            return [float(getters[vr]()) for vr in vrs]
        except KeyError:  # not a Real: pythonfmu's TypeError names the value reference
            return super().get_real(vrs)

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        setters = self._real_setters
        try:
            for vr, value in zip(vrs, values):
                setters[vr](value)
        except KeyError:
            super().set_real(vrs, values)

    def refresh_outputs(self) -> None:
        """Recompute all outputs from the current inputs and state (with `set_outputs`)."""
        raise NotImplementedError

    def set_outputs(self, values: tuple) -> None:
        """All outputs of a refreshing slave at once (a tuple in output_names order): they
        are then current for the inputs they were computed from. One reference is stored,
        not one attribute per output, and a refused step puts the previous tuple back."""
        self.output_values = values
        self.outputs_stale = False

    def _restore_outputs(self, values: Sequence[Any]) -> None:
        """Put back output values taken with `_outputs_of` (output_names order)."""
        if self.refreshes_outputs:
            self.output_values = values
        else:
            self.__dict__.update(zip(self.output_names, values))

    def read_parameters(self) -> Any:
        """The parameters dataclass built from the current parameter variables."""
        return self.parameters_type(**{
            f.name: (bool if isinstance(f.default, bool) else float)(getattr(self, f.name))
            for f in fields(self.parameters_type)})

    # ---- FMI life cycle -----------------------------------------------------------
    def fail(self, message: str) -> None:
        """Log an Error-status message (the caller then returns False: fmi2Discard)."""
        self.log(message, Fmi2Status.error)

    def warn(self, message: str) -> None:
        self.log(message, Fmi2Status.warning)

    def setup_experiment(self, start_time: float, stop_time: float | None,
                         tolerance: float | None) -> None:
        self.start_time = start_time

    def exit_initialization_mode(self) -> None:
        try:  # a parameters type may check its ranges when it is built
            params = self.read_parameters()
            self.validate(params)
        except ValueError as error:
            raise ValueError(f"invalid parameter: {error}") from None
        try:  # the inputs' start values were checked when set
            self.params = params
            self.initialise(params)
            problem = self._non_finite_output(self.calculated + self.real_outputs)
        except (ArithmeticError, ValueError) as error:
            problem = _arithmetic_problem(error)
        if problem is not None:
            self.params = None
            raise ValueError(f"initialisation failed: {problem}")

    def do_step(self, current_time: float, step_size: float) -> bool:
        # one chained test for the usual call (also false for NaN); _refuse_call says why not
        if not (self.params is not None and self.start_time <= current_time < math.inf
                and 0.0 < step_size < math.inf):
            return self._refuse_call(current_time, step_size)
        # What a step changes: the outputs and the hidden state (C-level getters: cheap).
        outputs, hidden = self._outputs_of(self.__dict__), self._hidden_of(self)
        try:
            self.step(step_size)
            if not math.isfinite(sum(self._outputs_of(self.__dict__))):
                problem = self._non_finite_output()
            else:
                return True
        except Exception as error:
            if not _domain_failure(error):  # a defect: fmi2Error naming it, the state kept
                self.restore_hidden_state(dict(zip(self.hidden_state, hidden)))
                self._restore_outputs(outputs)
                raise
            problem = _arithmetic_problem(error)
        if problem is None:
            return True
        self.restore_hidden_state(dict(zip(self.hidden_state, hidden)))
        self._restore_outputs(outputs)
        self.fail(f"step at t = {current_time} s of {step_size} s refused, state unchanged: "
                  f"{problem}{self._describe_state()}")
        return False

    def _refuse_call(self, current_time: float, step_size: float) -> bool:
        """Log why fmi2DoStep cannot be called so and return False (fmi2Discard)."""
        if self.params is None:
            self.fail("fmi2DoStep called before initialisation (fmi2ExitInitializationMode) "
                      "succeeded")
        elif not self.start_time <= current_time < math.inf:
            self.fail(f"communication point = {current_time} s is outside "
                      f"[{self.start_time}, inf) (start time of fmi2SetupExperiment)")
        else:
            self.fail(f"communication step size = {step_size} s is outside (0, inf)")
        return False

    @cached_property
    def _outputs_of(self) -> Callable[[dict[str, Any]], tuple]:
        """Tuple of the output values in the instance's namespace dict, in output_names
        order (a refreshing slave's output_values as they are)."""
        if self.refreshes_outputs:
            return itemgetter("output_values")
        return _tuple_getter(itemgetter, self.output_names)

    @cached_property
    def _hidden_of(self) -> Callable[[Any], tuple]:
        """Tuple of the hidden-state values of an instance, in hidden_state order."""
        return _tuple_getter(attrgetter, self.hidden_state)

    def _non_finite_output(self, names: list[str] | None = None) -> str | None:
        """A message naming the first of the Real variables names (default: the outputs)
        that is NaN or infinite, else None."""
        names = self.real_outputs if names is None else names
        values = {**self.__dict__, **dict(zip(self.output_names, self._outputs_of(self.__dict__)))}
        if math.isfinite(sum(values[name] for name in names)):
            return None
        for name in names:
            if not math.isfinite(values[name]):
                kind = "output" if name in self.output_names else "calculated parameter"
                return f"{kind} {name} would be {values[name]}, not a finite number"
        return None  # the finite values only overflowed in their sum

    def _describe_state(self) -> str:
        """' (inputs ...; state ...)': what set the step's dynamics, for error messages."""
        inputs = ", ".join(f"{name} = {getattr(self, name):.6g}"
                           for name, _, _ in self.real_input_bounds)
        state = getattr(self, "state", None)
        if isinstance(state, tuple) and hasattr(state, "_fields"):
            inputs += "; state " + ", ".join(f"{name} = {value:.6g}"
                                             for name, value in zip(state._fields, state))
        return f" (inputs {inputs})" if inputs else ""

    def _input_problem(self, name: str, value: float) -> str | None:
        """Error message naming the Real input name and its range when value is not finite,
        beyond the magnitudes or outside that range, else None."""
        info = self.info[name]
        low = -math.inf if info.min is None else info.min
        high = math.inf if info.max is None else info.max
        if not math.isfinite(value):
            return f"input {name} = {value} {info.unit} is not a finite number in [{low}, {high}]"
        magnitude = magnitude_problem(value)
        if magnitude:
            return f"input {name} = {value} {info.unit} {magnitude} (allowed [{low}, {high}])"
        if not low <= value <= high:
            return f"input {name} = {value} {info.unit} is outside [{low}, {high}]"
        return None

    def validate(self, params: Any) -> None:
        """Raise ValueError naming the first parameter outside its range."""
        check_ranges(params)

    def initialise(self, params: Any) -> None:
        raise NotImplementedError

    def step(self, dt: float) -> None:
        raise NotImplementedError

    # ---- state get/set: registered variables plus hidden state ------------------------
    def _get_fmu_state(self) -> dict[str, Any]:
        state = super()._get_fmu_state()
        state[STATE_MODEL] = type(self).__name__
        state[STATE_LAYOUT] = self.state_layout
        state[STATE_HIDDEN] = {name: _to_json(getattr(self, name))
                               for name in self.hidden_state}
        return state

    @cached_property
    def state_layout(self) -> str:
        """Key of the layout of this slave's FMU states: a digest of its variables (name,
        type, causality) and of the names of its hidden state."""
        text = "\n".join([f"{type(v).__name__} {v.causality.name} {v.name}"
                          for v in self.vars.values()]
                         + [f"hidden {name}" for name in self.hidden_state])
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Restore a state, after checking that it is one of this model and layout with
        values of the right types, finite numbers, inputs in their ranges and hidden state of
        this slave's shape, and then as a fresh initialisation would: its parameters in range
        (a ValueError names the variable). A refused state changes nothing."""
        variables = {var.name: var for var in self.vars.values()}
        hidden = self._checked_state(state, variables)
        saved = dict(self.__dict__)
        try:
            self._restore_state(state, hidden, variables)
        except Exception:
            self.__dict__.clear()  # the same dict: the setters' closures hold it
            self.__dict__.update(saved)
            raise

    def _checked_state(self, state: Any, variables: dict[str, ScalarVariable]
                       ) -> dict[str, Any]:
        """The hidden part of a state that may be restored (ValueError naming what is not)."""
        if self.params is None:
            raise self._state_problem("the instance is not initialised (set a state after "
                                      "fmi2ExitInitializationMode)")
        if not isinstance(state, dict):
            raise self._state_problem(f"a {type(state).__name__}, not an FMU state")
        model = type(self).__name__
        if state.get(STATE_MODEL) != model:
            raise self._state_problem(f"made by model {state.get(STATE_MODEL)!r}, not {model}")
        if state.get(STATE_LAYOUT) != self.state_layout:
            raise self._state_problem(
                f"layout {state.get(STATE_LAYOUT)!r} is not this {model}'s "
                f"{self.state_layout} (another version: other variables or hidden state)")
        expected = {*variables, STATE_MODEL, STATE_LAYOUT, STATE_HIDDEN}
        missing, extra = sorted(expected - set(state)), sorted(set(state) - expected)
        if missing or extra:
            raise self._state_problem(", ".join(
                [f"{name} is missing" for name in missing]
                + [f"{name} is not a variable of {model}" for name in extra]))
        for name, var in variables.items():
            value, kinds = state[name], STATE_TYPES[type(var)]
            if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
                raise self._state_problem(f"{name} = {value!r} is not of type {type(var).__name__}")
            if isinstance(var, Real) and not _finite(value):
                raise self._state_problem(f"{name} = {value} is not a finite number")
        for name, _, _ in self.real_input_bounds:
            problem = self._input_problem(name, state[name])
            if problem is not None:
                raise self._state_problem(problem)
        hidden = state[STATE_HIDDEN]
        if not isinstance(hidden, dict) or set(hidden) != set(self.hidden_state):
            raise self._state_problem(f"hidden state {hidden!r} does not hold "
                                      f"{', '.join(self.hidden_state) or 'nothing'}")
        for name in self.hidden_state:
            value, like = hidden[name], _to_json(getattr(self, name))
            if _shape(value) != _shape(like):
                raise self._state_problem(f"hidden state {name} = {value!r} is not of the "
                                          f"shape of {like!r} (numbers, booleans, lengths)")
            if not all(_finite(v) for v in _numbers(value)):
                raise self._state_problem(f"hidden state {name} = {value} is not finite")
        return hidden

    def _restore_state(self, state: dict[str, Any], hidden: dict[str, Any],
                       variables: dict[str, ScalarVariable]) -> None:
        """Take a checked state into effect (a ValueError names what a fresh initialisation
        would refuse)."""
        # a refreshing slave's outputs are computed again from the restored state, below
        skipped = set(self.output_names) if self.refreshes_outputs else set()
        for name, var in variables.items():  # direct: the parameter setters refuse after init
            if name not in skipped:
                value = state[name]
                setattr(self, var.local_name, float(value) if isinstance(var, Real) else value)
        try:
            params = self.read_parameters()
            self.validate(params)
        except ValueError as error:
            raise self._state_problem(f"invalid parameter: {error}") from None
        self.params = params
        self.restore_hidden_state(hidden)
        if self.refreshes_outputs:  # what the saved state read: the same inputs and state
            try:
                self.refresh_outputs()
                problem = self._non_finite_output()
            except (ArithmeticError, ValueError) as error:
                if not _domain_failure(error):
                    raise
                problem = _arithmetic_problem(error)
            if problem is not None:
                raise self._state_problem(problem)

    @staticmethod
    def _state_problem(problem: str) -> ValueError:
        return ValueError(f"FMU state refused: {problem}")

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        for name, value in hidden.items():
            setattr(self, name, value)

    # ---- model description ------------------------------------------------------------
    def to_xml(self, model_options: dict[str, str] = dict()) -> Element:  # noqa: B006
        root = super().to_xml(model_options)
        used_units = sorted({i.unit for i in self.info.values() if i.unit is not None})
        position = list(root).index(root.find("CoSimulation")) + 1
        root.insert(position, _unit_definitions(used_units))
        root.insert(position + 1, _type_definitions(used_units))

        initial_unknowns = []
        index_of: dict[str, int] = {}
        for index, element in enumerate(root.find("ModelVariables"), start=1):
            name = element.get("name")
            index_of[name] = index
            info = self.info[name]
            real = element.find("Real")
            if real is not None:
                real.set("declaredType", UNITS[info.unit][0])
                if info.unit in DISPLAY_UNITS:
                    real.set("displayUnit", DISPLAY_UNITS[info.unit][0])
                for key in ("min", "max"):
                    if getattr(info, key) is not None:
                        real.set(key, f"{getattr(info, key):.16g}")
            if element.get("initial") == "calculated":
                initial_unknowns.append(index)
        structure = root.find("ModelStructure")
        names = list(index_of)
        for unknown in structure.iterfind("Outputs/Unknown"):
            inputs = self.dependencies[names[int(unknown.get("index")) - 1]]
            unknown.set("dependencies", _indices(index_of[n] for n in inputs))
        # At initialisation the knowns also include the parameters, which the initial state
        # is computed from: every parameter is listed (a superset), with the inputs declared.
        parameters = [index_of[v.name] for v in self.vars.values()
                      if v.causality == Fmi2Causality.parameter]
        if initial_unknowns:
            node = SubElement(structure, "InitialUnknowns")
            for index in initial_unknowns:
                inputs = self.initial_dependencies.get(names[index - 1], ())
                dependencies = _indices([*parameters, *(index_of[n] for n in inputs)])
                SubElement(node, "Unknown", attrib={"index": str(index),
                                                    "dependencies": dependencies})
        return root


class MechanismSlave(ModelSlave):
    """Base of the mechanism slaves: a thin layer over a pure physics module.

    `physics` is the module, a `fmu_src.mechanism.Physics`: validate, initial_state, advance
    (one communication step with the inputs held), outputs, and switch_inputs, called only
    when one of its EVENT_INPUTS changes (the drive effort changes at every step and is no
    event). Subclasses register the variables: one input per field of physics.Inputs, of the
    same name, and one output per field of the Outputs, in their order.
    """

    physics: Any
    hidden_state = ("state", "previous_inputs")

    @property
    def parameters_type(self) -> type:
        """The physics module's Parameters: the FMU's parameters."""
        return self.physics.Parameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.state = None
        self.previous_inputs = None
        names = self.physics.EVENT_INPUTS
        # the event inputs of an Inputs tuple, as one comparable value (None: no events)
        self.event_values = (itemgetter(*(self.physics.Inputs._fields.index(n) for n in names))
                             if names else None)
        # the input variables' values in physics.Inputs order, from the instance's __dict__,
        # and an Inputs built from such a tuple at C level (Inputs._make is a Python call)
        self.input_values = _tuple_getter(itemgetter, self.physics.Inputs._fields)
        self.new_inputs = partial(tuple.__new__, self.physics.Inputs)

    def validate(self, params: Any) -> None:
        self.physics.validate(params)

    def inputs(self) -> Any:
        """The current inputs as a physics.Inputs."""
        return self.new_inputs(self.input_values(self.__dict__))

    def initialise(self, params: Any) -> None:
        missing = [n for n in self.physics.Inputs._fields if n not in self.info]
        if missing:
            raise TypeError(f"{type(self).__name__} has no input variable for "
                            f"{self.physics.__name__}.Inputs field(s) {', '.join(missing)}")
        self.state = self.physics.initial_state(params)
        self.previous_inputs = self.inputs()
        outputs = self.physics.outputs(params, self.previous_inputs, self.state)
        if outputs._fields != tuple(self.output_names):
            raise TypeError(f"{type(self).__name__} registers its outputs in another order "
                            f"than {self.physics.__name__}.Outputs")
        self.set_outputs(outputs)

    def step(self, dt: float) -> None:
        self.step_with(self.inputs(), dt)

    def step_with(self, u: Any, dt: float) -> None:
        """One communication step dt [s] with the inputs u (from `inputs()`)."""
        events = self.event_values
        if events is not None and events(u) != events(self.previous_inputs):
            self.switch_inputs(u)
        physics, params = self.physics, self.params
        self.state = state = physics.advance(params, u, self.state, dt)
        self.output_values = physics.outputs(params, u, state)  # set_outputs, inlined
        self.outputs_stale = False

    def switch_inputs(self, u: Any) -> None:
        """Book the change of event inputs from previous_inputs to u at this communication
        point."""
        self.state = self.physics.switch_inputs(self.params, self.previous_inputs, u, self.state)
        self.previous_inputs = u

    def refresh_outputs(self) -> None:
        self.set_outputs(self.physics.outputs(self.params, self.inputs(), self.state))

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        self.state = self.physics.State(*hidden["state"])
        self.previous_inputs = self.physics.Inputs(*hidden["previous_inputs"])


# The output rows every payload arm has (PayloadArmSlave.output_table), by name.
ARM_OUTPUTS = {row[0]: row for row in (
    ("theta", "rad", "Arm angle from the upward vertical, counter-clockwise positive "
                     "(the paper's phi = pi/2 - theta)"),
    ("omega", "rad/s", "Arm angular velocity"),
    ("E_p", "J", "Gravitational potential energy of link, payload and both counterweights"),
    ("E_kin", "J", "Kinetic energy of link, payload, counterweights and drive rotor"),
    ("M_g", "N.m", "Payload moment about O, -payload g w cos(phi) (eq. 8, paper's sign)"),
    ("M_u", "N.m", "Unbalanced moment M_b + M_g (eq. 16)"),
    ("W_drive", "J", "Cumulative work of tau_drive on the arm"),
    ("E_loss", "J", "Cumulative energy dissipated: pivot friction, payload picked up while "
                    "moving"),
    ("E_added", "J", "Cumulative energy brought in (+) or taken out (-) by payload joining or "
                     "leaving; E_p + E_kin + E_loss - W_drive - E_added is constant"),
)}


class PayloadArmSlave(MechanismSlave):
    """A one-link arm with a drive torque and a payload at distance w: inputs tau_drive and
    payload (physics.Inputs(tau_drive, payload)); outputs from the subclass's table."""

    # (name, unit, description) per output (ARM_OUTPUTS has the rows every arm shares), and
    # the inputs each depends on (ModelStructure): the payload's moment, inertia and weight
    output_table: tuple[tuple[str, str, str], ...] = ()
    input_dependencies: dict[str, tuple[str, ...]] = {
        name: ("payload",) for name in ("tau_gravity", "E_p", "E_kin", "M_g", "M_u")}
    # 1 ms is the harness's communication step; 20 s spans several strokes of a rocking
    # cycle and many periods of a default arm's free swing
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.add_input("tau_drive", 0.0, "N.m", "Drive torque on the arm about O, along theta")
        self.add_input("payload", 0.0, "kg", "Payload mass at distance w (the paper's G_pv/g)",
                       min=0.0)
        for name, unit, description in self.output_table:
            self.add_output(name, unit, description, self.input_dependencies.get(name, ()))



def _indices(indices: Any) -> str:
    """A ModelStructure dependencies attribute: variable indices in increasing order."""
    return " ".join(str(i) for i in sorted(indices))


def _unit_definitions(units: list[str]) -> Element:
    node = Element("UnitDefinitions")
    for unit in units:
        unit_node = SubElement(node, "Unit", attrib={"name": unit})
        SubElement(unit_node, "BaseUnit", attrib={k: str(v) for k, v in UNITS[unit][1].items()})
        if unit in DISPLAY_UNITS:
            name, factor = DISPLAY_UNITS[unit]
            SubElement(unit_node, "DisplayUnit", attrib={"name": name, "factor": f"{factor:.16g}"})
    return node


def _type_definitions(units: list[str]) -> Element:
    node = Element("TypeDefinitions")
    for unit in units:
        quantity = UNITS[unit][0]
        simple = SubElement(node, "SimpleType", attrib={"name": quantity})
        SubElement(simple, "Real", attrib={"quantity": quantity, "unit": unit})
    return node


def _refused_setter(name: str, causality: str) -> Callable[[Any], None]:
    """Setter of a variable FMI 2.0 does not let a host set (an output): refuses."""
    def refuse(value: Any) -> None:
        raise ValueError(f"{name} = {value!r} refused: {name} is of causality {causality}, "
                         "and only inputs, and parameters before initialisation, can be set "
                         "(FMI 2.0)")
    return refuse


def _domain_failure(error: BaseException) -> bool:
    """A refusal of the physics (DomainError) or a failed computation (ArithmeticError, the
    math module's ValueErrors), which refuse a step; anything else is a defect."""
    return isinstance(error, (ArithmeticError, DomainError)) or (
        isinstance(error, ValueError) and str(error) in MATH_ERRORS)


def _arithmetic_problem(error: ArithmeticError | ValueError) -> str:
    """The message of a failed step: ours as it is, the math module's and Python's
    arithmetic errors translated into what happened."""
    text = str(error)
    if isinstance(error, ValueError) and text not in MATH_ERRORS:
        return text
    return (f"the model's arithmetic failed ({text}): the parameters, inputs or state are "
            "beyond what double precision can represent")


def _tuple_getter(getter: Callable[..., Callable], names: Sequence[str]) -> Callable:
    """getter(*names) returning a tuple also for one name or none (itemgetter/attrgetter
    return the bare value for one name)."""
    if len(names) == 1:
        single = getter(names[0])
        return lambda source: (single(source),)
    if not names:
        return lambda source: ()
    return getter(*names)


def _numbers(value: Any) -> list[float | int]:
    """The numbers (not booleans) in a (nested) hidden-state value."""
    if isinstance(value, (list, tuple)):
        return [x for v in value for x in _numbers(v)]
    if isinstance(value, dict):
        return [x for v in value.values() for x in _numbers(v)]
    return [value] if isinstance(value, (float, int)) and not isinstance(value, bool) else []


def _finite(value: float | int) -> bool:
    """A finite number (an integer too large for a float is not)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _shape(value: Any) -> Any:
    """The structure of a JSON value: lists by their elements' shapes, dicts by key, and a
    leaf by its kind (float for any number, bool, str, None), for comparing hidden states."""
    if isinstance(value, (list, tuple)):
        return [_shape(v) for v in value]
    if isinstance(value, dict):
        return {key: _shape(v) for key, v in value.items()}
    if isinstance(value, bool) or value is None:
        return type(value)
    return float if isinstance(value, (float, int)) else type(value)


def _to_json(value: Any) -> Any:
    """Hidden state as JSON-compatible data (NamedTuples become lists)."""
    if isinstance(value, tuple):
        return [_to_json(v) for v in value]
    return value
