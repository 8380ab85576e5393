"""The base class of the FMUs' slaves (standard library only): life cycle and step policy.

`ModelSlave` is a thin FMI layer over a pure model module: the mechanisms, the DC motor
drive and the position controller all use it. Its variables are `fmu_src.fmi.variables`, its
FMU state `fmu_src.fmi.state`, its model description that of the FMI version it is bound to
(`fmu_src.fmi.binding`); `fmu_src.fmi.mechanism_slave` adds the step, event and state plumbing
every mechanism shares.

A bad parameter fails the exit from initialisation mode; a bad step size fails the step with
Discard (do_step returns False) after an Error-status log message (`fmu_src.fmi.failures`).
A refused step leaves the instance as it was before the call: `do_step` refuses a step
whose work would exceed the integrator's bound (`fmu_src.integration.MAX_SUBSTEPS`), that
the physics refuses (`fmu_src.parameters.DomainError`), whose arithmetic fails, or whose
outputs would not be finite, and restores the state. Any other exception of a step is a
defect: it propagates (Error, naming its type).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cached_property
from operator import attrgetter
from typing import Any

from fmu_src.fmi.failures import arithmetic_problem, domain_failure
from fmu_src.fmi.state import StatefulSlave
from fmu_src.fmi.variables import VariableInfo, tuple_getter
from fmu_src.fmi.vocabulary import Status
from fmu_src.parameters import check_ranges

__all__ = ["ModelSlave", "VariableInfo"]


class ModelSlave(StatefulSlave):
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

    # ---- FMI life cycle -----------------------------------------------------------
    def fail(self, message: str) -> None:
        """Log an Error-status message (the caller then returns False: Discard)."""
        self.report(message, Status.error)

    def warn(self, message: str) -> None:
        """Log a Warning-status message."""
        self.report(message, Status.warning)

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
            problem = arithmetic_problem(error)
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
            if not domain_failure(error):  # a defect: Error naming it, the state kept
                self.restore_hidden_state(dict(zip(self.hidden_state, hidden)))
                self._restore_outputs(outputs)
                raise
            problem = arithmetic_problem(error)
        if problem is None:
            return True
        self.restore_hidden_state(dict(zip(self.hidden_state, hidden)))
        self._restore_outputs(outputs)
        self.fail(f"step at t = {current_time} s of {step_size} s refused, state unchanged: "
                  f"{problem}{self._describe_state()}")
        return False

    def _refuse_call(self, current_time: float, step_size: float) -> bool:
        """Log why the step cannot be taken so and return False (Discard)."""
        calls = self.calls
        if self.params is None:
            self.fail(f"{calls.do_step} called before initialisation "
                      f"({calls.exit_initialization_mode}) succeeded")
        elif not self.start_time <= current_time < math.inf:
            self.fail(f"communication point = {current_time} s is outside "
                      f"[{self.start_time}, inf) (start time of {calls.setup_experiment})")
        else:
            self.fail(f"communication step size = {step_size} s is outside (0, inf)")
        return False

    @cached_property
    def _hidden_of(self) -> Callable[[Any], tuple]:
        """Tuple of the hidden-state values of an instance, in hidden_state order."""
        return tuple_getter(attrgetter, self.hidden_state)

    def _describe_state(self) -> str:
        """' (inputs ...; state ...)': what set the step's dynamics, for error messages."""
        inputs = ", ".join(f"{name} = {getattr(self, name):.6g}"
                           for name, _, _ in self.real_input_bounds)
        state = getattr(self, "state", None)
        if isinstance(state, tuple) and hasattr(state, "_fields"):
            inputs += "; state " + ", ".join(f"{name} = {value:.6g}"
                                             for name, value in zip(state._fields, state))
        return f" (inputs {inputs})" if inputs else ""

    def validate(self, params: Any) -> None:
        """Raise ValueError naming the first parameter outside its range."""
        check_ranges(params)

    def initialise(self, params: Any) -> None:
        raise NotImplementedError

    def step(self, dt: float) -> None:
        raise NotImplementedError
