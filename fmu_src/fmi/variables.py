"""The variables of the FMUs' slaves (standard library only): parameters from the model's
Parameters dataclass, inputs checked when set, outputs and the get/set caches.

Outputs are up to date whenever they are read: in a slave whose outputs are functions of
its state and inputs (`refresh_outputs`), an output read after an input was set is recomputed
first, so a host sees a changed payload in tau_gravity at once, not one step later. Outputs
declared independent of the inputs then read the same, which the tests check input by input.
A Real input set NaN, infinite or outside its range, a fixed parameter set after
initialisation, or an output set at all fails the set call (fmi2SetReal, fmi2SetBoolean,
fmi2SetString in FMI 2.0), and the value stays. The variables are declared through the FMI
version's adaptor (`fmu_src.fmi.binding`) in the layer's vocabulary (`fmu_src.fmi.vocabulary`).
"""

from __future__ import annotations

import builtins
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from functools import cached_property
from operator import itemgetter
from typing import Any

from fmu_src.fmi.binding import ModelAdaptor
from fmu_src.fmi.failures import refused_setter
from fmu_src.fmi.vocabulary import Causality, Initial, ValueType, Variability
from fmu_src.parameters import MAGNITUDE_LIMIT, magnitude_problem

SMALLEST = 1.0 / MAGNITUDE_LIMIT  # the smallest non-zero magnitude of an input


@dataclass(frozen=True)
class VariableInfo:
    """Model-description metadata of one variable."""

    unit: str | None
    description: str
    min: float | None = None
    max: float | None = None


class VariableSlave(ModelAdaptor):
    """The variables of a slave: its parameters (one per field of `parameters_type`, a frozen
    dataclass of `fmu_src.parameters.parameter` fields: bool ones Boolean, the others Real),
    the inputs and outputs registered with `add_input`/`add_output`, and the cached
    getters and setters of the Real get and set calls."""

    parameters_type: type

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
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
                self.add_parameter(f.name, ValueType.boolean,
                                   VariableInfo(None, meta["description"]))
            else:
                self.add_parameter(f.name, ValueType.real,
                                   VariableInfo(meta["unit"], meta["description"], meta["min"],
                                                meta["max"]))

    # ---- registration -------------------------------------------------------------
    def _add(self, value_type: ValueType, name: str, causality: Causality,
             variability: Variability, info: VariableInfo, initial: Initial | None = None,
             getter: Callable[[], Any] | None = None) -> None:
        """Declare a variable: inputs checked when set, which make the outputs stale; where
        the slave refreshes its outputs, outputs recomputed when read stale; parameters
        refused once initialised; and the others (outputs, locals) refusing to be set."""
        self.info[name] = info
        var = self.declare(value_type, name, causality, variability, info.description,
                           initial, getter)
        if causality is Causality.input:
            var.setter = self._input_setter(name)
        elif causality in (Causality.parameter, Causality.calculatedParameter):
            var.setter = self._parameter_setter(name, causality)
        else:
            var.setter = refused_setter(name, causality.name, self.standard)
            if causality is Causality.output and self.refreshes_outputs:
                var.getter = self._output_getter(name)
        for table in ("_real_getters", "_real_setters", "_output_positions"):  # built again
            self.__dict__.pop(table, None)

    def variable_names(self, causality: Causality) -> list[str]:
        """The names of the variables of one causality, in value-reference order."""
        return [var.name for var in self.vars.values() if self.causality_of(var) is causality]

    def _parameter_setter(self, name: str, causality: Causality) -> Any:
        """Setter of a fixed or calculated parameter: refused once initialised (the model
        would not use the new value) and always for a calculated one."""
        def set_parameter(value: Any) -> None:
            if causality is Causality.calculatedParameter:
                problem = f"{name} is a calculated parameter: it cannot be set"
            elif self.params is not None:
                problem = (f"{name} is a fixed parameter: it cannot be set after "
                           "initialisation (set it before "
                           f"{self.calls.exit_initialization_mode})")
            else:
                setattr(self, name, value)
                return
            raise ValueError(problem)
        return set_parameter

    def add_parameter(self, name: str, value_type: ValueType, info: VariableInfo) -> None:
        """A fixed parameter, held in the attribute of its name (set it first), which can
        be set only before initialisation."""
        self._add(value_type, name, Causality.parameter, Variability.fixed, info)

    def add_calculated_parameter(self, name: str, unit: str, description: str) -> None:
        """A parameter derived from the others at initialisation."""
        setattr(self, name, 0.0)
        self.calculated.append(name)
        self._add(ValueType.real, name, Causality.calculatedParameter, Variability.fixed,
                  VariableInfo(unit, description), Initial.calculated)

    def add_input(self, name: str, start: float | bool, unit: str | None, description: str,
                  min: float | None = None, max: float | None = None,
                  discrete: bool = False) -> None:
        """A Real (unit given) or Boolean (unit None) input held over a communication step;
        a Real one discrete (it changes only at events) or continuous."""
        setattr(self, name, start)
        if unit is None:
            value_type, variability = ValueType.boolean, Variability.discrete
        else:
            value_type = ValueType.real
            variability = Variability.discrete if discrete else Variability.continuous
            self.real_input_bounds.append((
                name, -MAGNITUDE_LIMIT if min is None else builtins.max(min, -MAGNITUDE_LIMIT),
                MAGNITUDE_LIMIT if max is None else builtins.min(max, MAGNITUDE_LIMIT)))
        self._add(value_type, name, Causality.input, variability,
                  VariableInfo(unit, description, min, max))

    def add_output(self, name: str, unit: str | None, description: str,
                   depends_on: tuple[str, ...] = (),
                   initial_depends_on: tuple[str, ...] | None = None) -> None:
        """A Real (unit given) or Boolean (unit None) output computed by the model.

        depends_on: the inputs whose current values the output depends on at a communication
        point (its ModelStructure dependencies); empty for a function of the state alone.
        initial_depends_on: the inputs it depends on at initialisation, where they differ (an
        output of the last step, computed at the start from the inputs then).
        """
        inputs = set(self.variable_names(Causality.input))
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
            value_type, variability = ValueType.boolean, Variability.discrete
        else:
            value_type, variability = ValueType.real, Variability.continuous
            self.real_outputs.append(name)
        self._add(value_type, name, Causality.output, variability,
                  VariableInfo(unit, description), Initial.calculated)

    def add_local(self, name: str, unit: str, description: str, getter: Callable[[], float],
                  initial_depends_on: tuple[str, ...] = ()) -> None:
        """A Real local variable the model computes (a continuous state or its derivative),
        read through getter; initial_depends_on: the inputs it depends on at
        initialisation."""
        self.initial_dependencies[name] = tuple(initial_depends_on)
        self._add(ValueType.real, name, Causality.local, Variability.continuous,
                  VariableInfo(unit, description), Initial.calculated, getter)

    @property
    def refreshes_outputs(self) -> bool:
        """The slave recomputes its outputs when read after an input was set."""
        return type(self).refresh_outputs is not VariableSlave.refresh_outputs

    # Closures over the instance's __dict__: they run at every get and set call.
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

    # the Real get and set calls: the adaptor's look each variable up and check its type per call
    @cached_property
    def _real_getters(self) -> dict[int, Callable[[], Any]]:
        """Getter of each Real variable by value reference (complete once registered)."""
        return {vr: var.getter for vr, var in self.vars.items()
                if self.type_of(var) is ValueType.real}

    @cached_property
    def _real_setters(self) -> dict[int, Callable[[Any], None]]:
        """Setter of each Real variable by value reference."""
        return {vr: var.setter for vr, var in self.vars.items()
                if self.type_of(var) is ValueType.real}

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
        except KeyError:  # not a Real: the adaptor's TypeError names the value reference
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

    @cached_property
    def _outputs_of(self) -> Callable[[dict[str, Any]], tuple]:
        """Tuple of the output values in the instance's namespace dict, in output_names
        order (a refreshing slave's output_values as they are)."""
        if self.refreshes_outputs:
            return itemgetter("output_values")
        return tuple_getter(itemgetter, self.output_names)

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


def tuple_getter(getter: Callable[..., Callable], names: Sequence[str]) -> Callable:
    """getter(*names) returning a tuple also for one name or none (itemgetter/attrgetter
    return the bare value for one name)."""
    if len(names) == 1:
        single = getter(names[0])
        return lambda source: (single(source),)
    if not names:
        return lambda source: ()
    return getter(*names)
