"""Model Exchange of a mechanism's slave (standard library only; docs/model_exchange.md).

A host's solver integrates the physics' own State, its cumulative energies included, so that
the energy ledger can be checked after a Model Exchange run as after a co-simulation. The
slave gives the solver what the physics module gives the co-simulation step
(`fmu_src.mechanism.Physics`):

- the derivatives: `physics.derivatives` in the regime (`physics.mode`) held since the last
  event, as `advance` holds it through each RK4 sub-step;
- the event indicators (`physics.event_indicators`): the events `advance` handles after each
  sub-step (an end stop reached, a slider or a carriage stopping), located by the host;
- the event update in event mode: a change of the event inputs (a lock, the payload; the
  FMU declares them discrete) booked by `physics.switch_inputs`, then the events the
  indicators signal (`physics.event_update`), then the regime the new state starts in. A
  discrete input takes effect at an event only: one set in continuous-time mode (FMI 2.0
  forbids it; FMPy's CVode sets every input again in its root function, also past an input
  event it has not reached) waits for the next event.

The FMU's runtime (fmu_src/runtime: the FMI 2.0 calls of fmi2_functions.c on
runtime_core.c) calls the `me_` methods and enforces the FMI state machine; these methods
check what only the model knows (the number of states and indicators, finite states, time
after the last event) and raise a ValueError naming it, which the runtime returns as Error
with its message. The FMI 2.0 ModelExchange element is `fmu_src.fmi.fmi2.model_description`'s.
"""

from __future__ import annotations

import math
from typing import Any

# the unit of a state's time derivative, by the state's unit
DERIVATIVE_UNITS = {"rad": "rad/s", "rad/s": "rad/s2", "m": "m/s", "m/s": "m/s2", "J": "W"}


def derivative_name(state: str) -> str:
    """The name of the variable of a continuous state's time derivative (der(x), the
    structured naming convention's)."""
    return f"der({state})"


class ModelExchange:
    """The Model Exchange methods of a `MechanismSlave` (module docstring), each named in its
    docstring after the FMI 2.0 call the runtime makes it for.

    The slave keeps, besides its state and the inputs of the last event (`previous_inputs`),
    the regime held since the last event (`mode`) and the time of the last event
    (`event_time`).
    """

    physics: Any
    params: Any
    state: Any
    previous_inputs: Any
    mode: tuple[int, ...] = ()
    event_time: float = 0.0

    @property
    def me_state_count(self) -> int:
        """The number of continuous states, nx (the runtime reads it at instantiation)."""
        return len(self.physics.State._fields)

    @property
    def me_indicator_count(self) -> int:
        """The number of event indicators, ni (the runtime reads it at instantiation)."""
        return len(self.physics.EVENT_INDICATORS)

    # ---- the runtime's calls -----------------------------------------------------
    def me_set_time(self, time: float) -> None:
        """fmi2SetTime: the time of the next evaluations [s], not before the last event."""
        if not -math.inf < time < math.inf:
            raise ValueError(f"time = {time} s is not a finite number")
        if time < self.event_time:
            raise ValueError(f"time = {time!r} s is before the last event, at "
                             f"{self.event_time!r} s: a solver may not integrate back across "
                             "an event (restore an FMU state saved before it instead)")
        self.me_time = time

    def me_set_continuous_states(self, values: list[float]) -> None:
        """fmi2SetContinuousStates: the whole State, in its order, every value finite."""
        fields = self._state_fields("nx", len(values))
        bad = [f"{name} = {value}" for name, value in zip(fields, values)
               if not -math.inf < value < math.inf]
        if bad:
            raise ValueError(f"continuous states refused, not finite: {', '.join(bad)}")
        self.state = self.physics.State(*values)
        self.outputs_stale = True

    def me_get_continuous_states(self, nx: int) -> list[float]:
        """fmi2GetContinuousStates."""
        self._state_fields("nx", nx)
        return list(self._evaluation()[2])

    def me_get_nominals(self, nx: int) -> list[float]:
        """fmi2GetNominalsOfContinuousStates: `physics.state_nominals` (all 1 while the
        parameters are not valid yet)."""
        fields = self._state_fields("nx", nx)
        try:
            p = self._evaluation()[0]
        except ValueError:   # parameters still being set
            return [1.0] * len(fields)
        return list(self.physics.state_nominals(p))

    def me_get_derivatives(self, nx: int) -> list[float]:
        """fmi2GetDerivatives: `physics.derivatives` at the state and inputs, in the regime
        held."""
        self._state_fields("nx", nx)
        p, u, s, mode = self._evaluation()
        return list(self.physics.derivatives(p, u, s, None, mode))

    def me_get_event_indicators(self, ni: int) -> list[float]:
        """fmi2GetEventIndicators: `physics.event_indicators` in the regime held."""
        count = len(self.physics.EVENT_INDICATORS)
        if ni != count:
            raise ValueError(f"ni = {ni} is not the number of event indicators, {count}"
                             + self._names(self.physics.EVENT_INDICATORS))
        return list(self.physics.event_indicators(*self._evaluation()))

    def me_enter_event_mode(self) -> None:
        """fmi2EnterEventMode: the event's time is the last set; discrete inputs may change."""
        self.event_time = self.me_time

    def me_new_discrete_states(self) -> tuple[bool, bool, bool, bool, bool, float]:
        """fmi2NewDiscreteStates: book the change of the event inputs since the last event
        (`switch_inputs`), then the state events (`physics.event_update`), then take the
        regime the state starts in. Returns the fmi2EventInfo: (newDiscreteStatesNeeded,
        terminateSimulation, nominalsOfContinuousStatesChanged,
        valuesOfContinuousStatesChanged, nextEventTimeDefined, nextEventTime); one call
        settles the event (the update of a settled state changes nothing)."""
        physics, p, u = self.physics, self.params, self.inputs()
        before = self.state
        self.check_inputs(u)
        events = self.event_values
        if events is not None and events(u) != events(self.previous_inputs):
            self.switch_inputs(u)
        self.previous_inputs = u
        self.state = physics.event_update(p, u, self.state, self.mode)
        self.mode = physics.mode(p, u, self.state)
        self.outputs_stale = True
        return False, False, False, tuple(self.state) != tuple(before), False, 0.0

    def me_enter_continuous_time_mode(self) -> None:
        """fmi2EnterContinuousTimeMode: the event inputs are held until the next event."""

    def me_completed_integrator_step(self) -> tuple[bool, bool]:
        """fmi2CompletedIntegratorStep: (enterEventMode, terminateSimulation). An event is
        asked for where the state has left the regime held without an indicator crossing
        zero (a carriage broken loose from rest, whose screw's law is continuous there,
        reversing later), so that the regime is taken again."""
        p, u, s, mode = self._evaluation()
        return self.physics.mode(p, u, s) != mode, False

    # ---- the rest of the slave ----------------------------------------------------
    def _evaluation(self) -> tuple[Any, Any, Any, tuple[int, ...]]:
        """(parameters, inputs, state, regime) the inquiries evaluate: the instance's once
        initialised, its event inputs those the last event took (a discrete input set
        since takes effect at the next event); in Initialization Mode, those the parameters
        and inputs set so far start from (a ValueError names a parameter out of its
        range)."""
        u = self.inputs()
        if self.params is not None:
            held = self.previous_inputs   # the event inputs as the last event took them
            for name in self.physics.EVENT_INPUTS:
                u = u._replace(**{name: getattr(held, name)})
            return self.params, u, self.state, self.mode
        p = self.read_parameters()
        self.validate(p)
        s = self.physics.initial_state(p)
        return p, u, s, self.physics.mode(p, u, s)

    def check_inputs(self, u: Any) -> None:
        """Raise a ValueError naming an input value the physics cannot take (at an event in
        Model Exchange; `step` refuses such a step in co-simulation)."""

    def _state_fields(self, argument: str, count: int) -> tuple[str, ...]:
        """The State's fields; a ValueError unless count (the host's nx) is their number."""
        fields = self.physics.State._fields
        if count != len(fields):
            raise ValueError(f"{argument} = {count} is not the number of continuous states, "
                             f"{len(fields)} ({', '.join(fields)})")
        return fields

    @staticmethod
    def _names(declared: tuple[Any, ...]) -> str:
        return f" ({', '.join(v.name for v in declared)})" if declared else ""
