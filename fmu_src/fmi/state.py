"""Saving and restoring the FMU state of a slave: its variables plus its hidden state
(standard library only).

A restored FMU state must be one of this model and layout, of the right types, and is
validated like a fresh initialisation; a refused one changes nothing.
"""

from __future__ import annotations

import hashlib
import math
from functools import cached_property
from typing import Any

from fmu_src.fmi.failures import arithmetic_problem, domain_failure
from fmu_src.fmi.variables import VariableSlave
from fmu_src.fmi.vocabulary import Causality, ValueType

# keys of an FMU state besides its variables' names
STATE_MODEL, STATE_LAYOUT, STATE_HIDDEN = "__model__", "__layout__", "__hidden__"
REGIME_SIZE = 4  # the longest regime a hidden state may hold
# the Python types a variable's value in an FMU state may have, by its type
STATE_TYPES = {ValueType.real: (float, int), ValueType.boolean: (bool,),
               ValueType.integer: (int,), ValueType.string: (str,)}


class StatefulSlave(VariableSlave):
    """A slave whose FMU state can be saved and restored: its registered variables plus the
    attributes listed in `hidden_state` (JSON-compatible once `_to_json` has converted them)."""

    hidden_state: tuple[str, ...] = ()
    # hidden state that is a regime: a list of -1, 0 and 1 whose length depends on the state
    # (a Model Exchange mode, `fmu_src.mechanism.Physics.mode`)
    hidden_regimes: tuple[str, ...] = ("mode",)

    def _get_fmu_state(self) -> dict[str, Any]:
        # the variables that hold a value of their own (not the local variables computed
        # from the hidden state: Model Exchange's continuous states and their derivatives)
        state = {var.name: var.getter() for var in self._saved_variables().values()}
        state[STATE_MODEL] = type(self).__name__
        state[STATE_LAYOUT] = self.state_layout
        state[STATE_HIDDEN] = {name: _to_json(getattr(self, name))
                               for name in self.hidden_state}
        return state

    @cached_property
    def state_layout(self) -> str:
        """Key of the layout of this slave's FMU states: a digest of its variables (name,
        type, causality) and of the names of its hidden state."""
        text = "\n".join([f"{self.type_of(v).value} {self.causality_of(v).name} {v.name}"
                          for v in self.vars.values()]
                         + [f"hidden {name}" for name in self.hidden_state])
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Restore a state, after checking that it is one of this model and layout with
        values of the right types, finite numbers, inputs in their ranges and hidden state of
        this slave's shape, and then as a fresh initialisation would: its parameters in range
        (a ValueError names the variable). A refused state changes nothing."""
        variables = self._saved_variables()
        hidden = self._checked_state(state, variables)
        saved = dict(self.__dict__)
        try:
            self._restore_state(state, hidden, variables)
        except Exception:
            self.__dict__.clear()  # the same dict: the setters' closures hold it
            self.__dict__.update(saved)
            raise

    def _saved_variables(self) -> dict[str, Any]:
        """The variables an FMU state holds, by name: all but the local ones (computed from
        the hidden state)."""
        return {var.name: var for var in self.vars.values()
                if self.causality_of(var) is not Causality.local}

    def _checked_state(self, state: Any, variables: dict[str, Any]) -> dict[str, Any]:
        """The hidden part of a state that may be restored (ValueError naming what is not)."""
        if self.params is None:
            raise self._state_problem("the instance is not initialised (set a state after "
                                      f"{self.calls.exit_initialization_mode})")
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
            value_type = self.type_of(var)
            value, kinds = state[name], STATE_TYPES[value_type]
            if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
                raise self._state_problem(f"{name} = {value!r} is not of type {value_type.value}")
            if value_type is ValueType.real and not _finite(value):
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
            if name in self.hidden_regimes:
                if not (isinstance(value, list) and len(value) <= REGIME_SIZE and all(
                        v in (-1, 0, 1) and not isinstance(v, bool) for v in value)):
                    raise self._state_problem(f"hidden state {name} = {value!r} is not a "
                                              f"regime (up to {REGIME_SIZE} of -1, 0 and 1)")
                continue
            if _shape(value) != _shape(like):
                raise self._state_problem(f"hidden state {name} = {value!r} is not of the "
                                          f"shape of {like!r} (numbers, booleans, lengths)")
            if not all(_finite(v) for v in _numbers(value)):
                raise self._state_problem(f"hidden state {name} = {value} is not finite")
        return hidden

    def _restore_state(self, state: dict[str, Any], hidden: dict[str, Any],
                       variables: dict[str, Any]) -> None:
        """Take a checked state into effect (a ValueError names what a fresh initialisation
        would refuse)."""
        # a refreshing slave's outputs are computed again from the restored state, below
        skipped = set(self.output_names) if self.refreshes_outputs else set()
        for name, var in variables.items():  # direct: the parameter setters refuse after init
            if name not in skipped:
                value = state[name]
                real = self.type_of(var) is ValueType.real
                setattr(self, var.local_name, float(value) if real else value)
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
                if not domain_failure(error):
                    raise
                problem = arithmetic_problem(error)
            if problem is not None:
                raise self._state_problem(problem)

    @staticmethod
    def _state_problem(problem: str) -> ValueError:
        return ValueError(f"FMU state refused: {problem}")

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        for name, value in hidden.items():
            setattr(self, name, value)


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
