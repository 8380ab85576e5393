"""The slave of a mechanism, over its pure physics module (standard library only)."""

from __future__ import annotations

from functools import partial
from operator import itemgetter
from typing import Any

from fmu_src.fmi.slave import ModelSlave
from fmu_src.fmi.variables import tuple_getter


class MechanismSlave(ModelSlave):
    """Base of the mechanism slaves: a thin layer over a pure physics module.

    `physics` is the module, a `fmu_src.mechanism.Physics`: validate, initial_state, advance
    (one communication step with the inputs held), outputs, and switch_inputs, called only
    when one of its EVENT_INPUTS changes (the drive effort changes at every step and is no
    event). The slave registers its variables from the physics module: the parameters from
    its Parameters, then the subclass's `calculated_parameters` (set from the Parameters'
    attributes of their names at initialisation), the inputs from its INPUT_VARIABLES and
    the outputs from its OUTPUT_VARIABLES (`fmu_src.mechanism.input_variables`).
    """

    physics: Any
    hidden_state = ("state", "previous_inputs")
    # (name, unit, description) of each parameter the Parameters derive from the others
    calculated_parameters: tuple[tuple[str, str, str], ...] = ()

    @property
    def parameters_type(self) -> type:
        """The physics module's Parameters: the FMU's parameters."""
        return self.physics.Parameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        for name, unit, description in self.calculated_parameters:
            self.add_calculated_parameter(name, unit, description)
        for v in self.physics.INPUT_VARIABLES:
            self.add_input(v.name, v.start, v.unit, v.description, min=v.min, max=v.max)
        for v in self.physics.OUTPUT_VARIABLES:
            self.add_output(v.name, v.unit, v.description, v.depends_on)
        self.state = None
        self.previous_inputs = None
        names = self.physics.EVENT_INPUTS
        # the event inputs of an Inputs tuple, as one comparable value (None: no events)
        self.event_values = (itemgetter(*(self.physics.Inputs._fields.index(n) for n in names))
                             if names else None)
        # the input variables' values in physics.Inputs order, from the instance's __dict__,
        # and an Inputs built from such a tuple at C level (Inputs._make is a Python call)
        self.input_values = tuple_getter(itemgetter, self.physics.Inputs._fields)
        self.new_inputs = partial(tuple.__new__, self.physics.Inputs)

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
        point."""
        self.state = self.physics.switch_inputs(self.params, self.previous_inputs, u, self.state)
        self.previous_inputs = u

    def refresh_outputs(self) -> None:
        self.set_outputs(self.physics.outputs(self.params, self.inputs(), self.state))

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        self.state = self.physics.State(*hidden["state"])
        self.previous_inputs = self.physics.Inputs(*hidden["previous_inputs"])
