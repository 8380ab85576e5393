"""The slave of a mechanism, over its pure physics module (standard library only)."""

from __future__ import annotations

from functools import partial
from operator import itemgetter
from typing import Any

from fmu_src.fmi.model_exchange import DERIVATIVE_UNITS, ModelExchange, derivative_name
from fmu_src.fmi.slave import ModelSlave
from fmu_src.fmi.variables import tuple_getter


class MechanismSlave(ModelExchange, ModelSlave):
    """Base of the mechanism slaves: a thin layer over a pure physics module, for
    Co-Simulation and Model Exchange (`fmu_src.fmi.model_exchange`).

    `physics` is the module, a `fmu_src.mechanism.Physics`: validate, initial_state, advance
    (one communication step with the inputs held), outputs, and switch_inputs, called only
    when one of its EVENT_INPUTS changes (the drive effort changes at every step and is no
    event). The slave registers its variables from the physics module: the parameters from
    its Parameters, then the subclass's `calculated_parameters` (set from the Parameters'
    attributes of their names at initialisation), the inputs from its INPUT_VARIABLES (the
    EVENT_INPUTS discrete), the outputs from its OUTPUT_VARIABLES
    (`fmu_src.mechanism.input_variables`), then Model Exchange's continuous states that no
    output reports (STATE_VARIABLES) and the derivative der(x) of every state x.
    """

    physics: Any
    hidden_state = ("state", "previous_inputs", "mode", "event_time")
    # (name, unit, description) of each parameter the Parameters derive from the others
    calculated_parameters: tuple[tuple[str, str, str], ...] = ()

    @property
    def parameters_type(self) -> type:
        """The physics module's Parameters: the FMU's parameters."""
        return self.physics.Parameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        physics = self.physics
        for name, unit, description in self.calculated_parameters:
            self.add_calculated_parameter(name, unit, description)
        for v in physics.INPUT_VARIABLES:
            self.add_input(v.name, v.start, v.unit, v.description, min=v.min, max=v.max,
                           discrete=v.name in physics.EVENT_INPUTS)
        for v in physics.OUTPUT_VARIABLES:
            self.add_output(v.name, v.unit, v.description, v.depends_on)
        self.state = None
        self.previous_inputs = None
        self.mode = ()
        self.event_time = self.me_time = 0.0
        self._add_model_exchange_variables()
        names = physics.EVENT_INPUTS
        # the event inputs of an Inputs tuple, as one comparable value (None: no events)
        self.event_values = (itemgetter(*(physics.Inputs._fields.index(n) for n in names))
                             if names else None)
        # the input variables' values in physics.Inputs order, from the instance's __dict__,
        # and an Inputs built from such a tuple at C level (Inputs._make is a Python call)
        self.input_values = tuple_getter(itemgetter, physics.Inputs._fields)
        self.new_inputs = partial(tuple.__new__, physics.Inputs)

    def _add_model_exchange_variables(self) -> None:
        """The continuous states no output reports and each state's derivative, as local
        variables; `state_variables` names the variable of each State field in order and
        `derivative_of` maps each derivative's name to its state's."""
        physics = self.physics
        fields = physics.State._fields
        units = {v.name: v.unit for v in (*physics.OUTPUT_VARIABLES, *physics.STATE_VARIABLES)}
        descriptions = {v.name: v.description
                        for v in (*physics.OUTPUT_VARIABLES, *physics.STATE_VARIABLES)}
        for v in physics.STATE_VARIABLES:
            self.add_local(v.name, v.unit, v.description,
                           partial(self._state_value, fields.index(v.name)))
        inputs = tuple(v.name for v in physics.INPUT_VARIABLES)
        self.state_variables = fields
        self.derivative_of = {}
        for index, name in enumerate(fields):
            self.derivative_of[derivative_name(name)] = name
            self.add_local(derivative_name(name), DERIVATIVE_UNITS[units[name]],
                           f"Time derivative of {name}: {descriptions[name][0].lower()}"
                           f"{descriptions[name][1:]}", partial(self._derivative_value, index),
                           initial_depends_on=inputs)

    def _state_value(self, index: int) -> float:
        """The State component at index (0 before initialisation)."""
        return 0.0 if self.state is None else float(self.state[index])

    def _derivative_value(self, index: int) -> float:
        """The time derivative of the State component at index, at the current state and
        inputs in the regime held (0 before initialisation)."""
        if self.params is None:
            return 0.0
        return float(self.physics.derivatives(self.params, self.inputs(), self.state, None,
                                              self.mode)[index])

    def validate(self, params: Any) -> None:
        self.physics.validate(params)

    def inputs(self) -> Any:
        """The current inputs as a physics.Inputs."""
        return self.new_inputs(self.input_values(self.__dict__))

    def initialise(self, params: Any) -> None:
        for name, _, _ in self.calculated_parameters:
            setattr(self, name, getattr(params, name))
        self.state = self.physics.initial_state(params)
        self.previous_inputs = self.inputs()
        self.mode = self.physics.mode(params, self.previous_inputs, self.state)
        self.event_time = self.me_time = self.start_time
        self.set_outputs(self.physics.outputs(params, self.previous_inputs, self.state))

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
        point (or Model Exchange event)."""
        self.state = self.physics.switch_inputs(self.params, self.previous_inputs, u, self.state)
        self.previous_inputs = u

    def refresh_outputs(self) -> None:
        self.set_outputs(self.physics.outputs(self.params, self.inputs(), self.state))

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        self.state = self.physics.State(*hidden["state"])
        self.previous_inputs = self.physics.Inputs(*hidden["previous_inputs"])
        self.mode = tuple(int(x) for x in hidden["mode"])
        self.event_time = float(hidden["event_time"])
