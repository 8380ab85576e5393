"""The one interface of the FMUs of fmu_src (standard library only; docs/adding_a_mechanism.md).

`Physics` is the contract every mechanism's pure physics module meets: the slave
(`fmu_src.fmi.mechanism_slave.MechanismSlave`), the monolithic reference
(`harness.engines.reference`) and the tests use a mechanism through it alone.

`Registration` is what the harness knows of an FMU beyond its slave class, declared once, as
`REGISTRATION`, in the FMU's slave script `fmu_src/<folders>/<Model>.py`: the build finds the
FMUs by it (`harness.registry`), and the OSP ports, the documented reference run, the monolithic
reference, the bench's step loops, the plots and the tests' per-model cases are read from it.
Everything in it is plain data, so the FMU carries it with the standard library only. """

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Protocol, Union


class Physics(Protocol):
    """A mechanism's pure physics module (no FMI, no I/O). Units are SI.

    Parameters is a frozen dataclass with a default per field; Inputs and State are
    NamedTuples (Inputs with a default per field, State's cumulative energies last); Outputs
    a NamedTuple named like the FMU's output variables. INPUT_VARIABLES and OUTPUT_VARIABLES
    declare the FMU's variable of each Inputs and Outputs field (`input_variables`,
    `output_variables`).
    """

    Parameters: type
    Inputs: type
    State: type
    Outputs: type
    INPUT_VARIABLES: tuple[Variable, ...]
    OUTPUT_VARIABLES: tuple[Variable, ...]
    # inputs whose change at a communication point changes the state (a payload caught or
    # released, a lock engaged): switch_inputs books it; () when there are none
    EVENT_INPUTS: tuple[str, ...]

    def validate(self, params: Any) -> None:
        """ValueError naming the parameter and its allowed range."""

    def initial_state(self, p: Any) -> Any:
        """The State at the start time."""

    def derivatives(self, p: Any, u: Any, s: Any, rates: Any = None, mode: Any = None) -> Any:
        """ds/dt as a State, for inputs u held constant; rates (Inputs): d/dt of the inputs
        that ramp (masses joining or leaving while the mechanism moves), None for none; mode:
        the regime held since the last event (`mode`), None to decide it from s."""

    def characteristic_rate(self, p: Any, u: Any, s: Any) -> float:
        """The fastest rate of the local dynamics [1/s]: sets the integration sub-step."""

    def advance(self, p: Any, u: Any, s: Any, dt: float) -> Any:
        """The State after one communication step dt [s] with the inputs held; a
        `fmu_src.parameters.DomainError` (or an ArithmeticError) when the physics cannot
        integrate it, which the FMU turns into a refused step (status Discard)."""

    def switch_inputs(self, p: Any, before: Any, after: Any, s: Any) -> Any:
        """The State just after the event inputs change from before to after."""

    def outputs(self, p: Any, u: Any, s: Any) -> Any:
        """The Outputs at the state s with the inputs u."""

    # ---- Model Exchange: the events the step locates inside itself, for a host's solver
    # (docs/adding_a_mechanism.md); no_mode, no_event_indicators and no_event_update serve a
    # smooth mechanism
    # the variables of the State fields that no output reports (`state_variables`)
    STATE_VARIABLES: tuple[Variable, ...]
    # the FMU's event indicators, one `variable(unit, description)` each, named, in order
    EVENT_INDICATORS: tuple[Variable, ...]

    def mode(self, p: Any, u: Any, s: Any) -> tuple[int, ...]:
        """The regime the state and inputs start in (a friction state, a screw's direction),
        held by a host's solver until the next event; () for a mechanism without one."""

    def event_indicators(self, p: Any, u: Any, s: Any, mode: tuple[int, ...]
                         ) -> tuple[float, ...]:
        """One value per EVENT_INDICATORS, positive while the regime mode holds; an event
        where one crosses to zero or below (a stop reached, a slider stopping)."""

    def event_update(self, p: Any, u: Any, s: Any, mode: tuple[int, ...]) -> Any:
        """The State after the events an indicator's crossing signals (a stop's impact, a
        slider sticking), the energy they take booked in the ledger; s where there is none
        (so that a second call changes nothing)."""

    def state_nominals(self, p: Any) -> tuple[float, ...]:
        """The magnitude of each State component [its unit] a solver's absolute tolerance
        scales with."""


@dataclass(frozen=True)
class Variable:
    """The FMI variable of one Inputs or Outputs field: unit (None: a Boolean), description,
    for an input its start (the field's default) and range, for an output the inputs it
    depends on at a communication point (its ModelStructure dependencies; () for a function
    of the state alone)."""

    unit: str | None
    description: str
    depends_on: tuple[str, ...] = ()
    min: float | None = None
    max: float | None = None
    name: str = ""
    start: float | bool = 0.0


def variable(unit: str | None, description: str, *, depends_on: tuple[str, ...] = (),
             min: float | None = None, max: float | None = None) -> Variable:
    """The declaration of one input or output variable, named after its field by
    `input_variables`/`output_variables` (as `fmu_src.parameters.parameter` declares a
    parameter)."""
    return Variable(unit, description, tuple(depends_on), min, max)


def _named(fields_of: type, declared: Mapping[str, Variable]) -> tuple[Variable, ...]:
    """The declared variables named after the fields of the NamedTuple fields_of; TypeError
    unless they declare exactly its fields, in its order."""
    names = fields_of._fields
    if tuple(declared) != names:
        missing = [n for n in names if n not in declared]
        extra = [n for n in declared if n not in names]
        raise TypeError(f"the variables of {fields_of.__qualname__} must declare its fields "
                        f"{', '.join(names)} in this order (missing: {', '.join(missing) or '-'};"
                        f" not fields: {', '.join(extra) or '-'})")
    return tuple(replace(v, name=n) for n, v in declared.items())


def input_variables(inputs: type, **declared: Variable) -> tuple[Variable, ...]:
    """The input variables of a physics module's Inputs, one `variable` per field in its
    order, each starting at the field's default; TypeError naming the fields undeclared or
    declared without a field, or an input declared with dependencies."""
    named = _named(inputs, declared)
    dependent = [v.name for v in named if v.depends_on]
    if dependent:
        raise TypeError(f"inputs {', '.join(dependent)} of {inputs.__qualname__} declare "
                        "depends_on, which only an output has")
    return tuple(replace(v, start=inputs._field_defaults[v.name]) for v in named)


def output_variables(outputs: type, inputs: type, **declared: Variable) -> tuple[Variable, ...]:
    """The output variables of a physics module's Outputs, one `variable` per field in its
    order; TypeError naming the fields undeclared or declared without a field, or a
    dependency on a name that is no field of inputs."""
    named = _named(outputs, declared)
    unknown = [f"{v.name} on {n}" for v in named for n in v.depends_on
               if n not in inputs._fields]
    if unknown:
        raise TypeError(f"outputs of {outputs.__qualname__} depend on no field of "
                        f"{inputs.__qualname__}: {', '.join(unknown)}")
    return named


def state_variables(state: type, outputs: type, **declared: Variable) -> tuple[Variable, ...]:
    """The variables of the State fields that no output of the same name reports (the
    continuous states of Model Exchange are the State's fields, each a variable: an output
    where one reports it, else one of these); TypeError unless exactly those are declared."""
    missing = [n for n in state._fields if n not in outputs._fields]
    if sorted(declared) != sorted(missing):
        raise TypeError(f"the state variables of {state.__qualname__} must declare its fields "
                        f"that no output reports: {', '.join(missing) or 'none'} (declared: "
                        f"{', '.join(declared) or 'none'})")
    return tuple(replace(v, name=n) for n, v in declared.items())


def no_input_events(p: Any, before: Any, after: Any, s: Any) -> Any:
    """`switch_inputs` of a mechanism whose EVENT_INPUTS is empty: the state, unchanged."""
    return s


def variable_named(name: str, declared: Variable) -> Variable:
    """declared with its name (an event indicator's, which no field names)."""
    return replace(declared, name=name)


def no_mode(p: Any, u: Any, s: Any) -> tuple[int, ...]:
    """`mode` of a mechanism with one smooth regime."""
    return ()


def no_event_indicators(p: Any, u: Any, s: Any, mode: tuple[int, ...]) -> tuple[float, ...]:
    """`event_indicators` of a mechanism without state events."""
    return ()


def no_event_update(p: Any, u: Any, s: Any, mode: tuple[int, ...]) -> Any:
    """`event_update` of a mechanism without state events: the state, unchanged."""
    return s


# The one-link figure's panels after the link angle (Franchetti et al. 2021, Figure 5), as
# (title, unit): a one-link mechanism draws its outputs in them (Registration.plot_panels), so
# that the variants of one scenario, whatever their models, share them
ENERGY_PANEL = ("(b) energies", "J")
ADJUSTMENT_PANEL = ("(c) adjuster travel and payload", "mm | kg")
GEOMETRY_PANEL = ("(d) spring length or counterweight position", "mm")

# The one-link figure's panels after the link angle, as (title, unit): Franchetti et al. 2021,
# Figure 5 (b) energies, (c) adjuster travel and payload (two quantities, so two panels here)
# and (d) spring length. A one-link mechanism draws its outputs in them
# (Registration.plot_panels), so that the variants of one scenario, whatever their models,
# share them
ENERGY_PANEL = ("energies", "J")
TRAVEL_PANEL = ("adjuster travel", "mm")
PAYLOAD_PANEL = ("payload", "kg")
GEOMETRY_PANEL = ("spring length or counterweight position", "mm")


def one_link_panels(energies: tuple[str, ...], travel: tuple[str, ...],
                    geometry: tuple[str, ...], payload: tuple[str, ...] = ("payload",)
                    ) -> tuple[tuple[str, str, tuple[str, ...]], ...]:
    """The plot_panels of a one-link mechanism: the variables it draws in ENERGY_PANEL,
    TRAVEL_PANEL (its adjuster's travel, none for a mechanism without one), PAYLOAD_PANEL and
    GEOMETRY_PANEL; a panel with no variable is left out."""
    panels = ((*ENERGY_PANEL, energies), (*TRAVEL_PANEL, travel), (*PAYLOAD_PANEL, payload),
              (*GEOMETRY_PANEL, geometry))
    return tuple(panel for panel in panels if panel[2])


# OSP-IS port kinds (harness.fmu.osp): effort and flow of each
ANGULAR = "AngularMechanicalPort"   # Torque [N.m], AngularVelocity [rad/s]
LINEAR = "LinearMechanicalPort"     # Force [N], LinearVelocity [m/s]
ELECTROMAGNETIC = "ElectromagneticPort"  # Voltage [V], Current [A]


@dataclass(frozen=True)
class Port:
    """A power port of the FMU (an OSP-IS variable group of two): its effort and flow
    variables; for a mechanism's joint also its position, the variables the co-simulation
    master sets (the effort) and reads (position and flow) at every step."""

    kind: str        # ANGULAR, LINEAR or ELECTROMAGNETIC
    name: str        # the effort and flow groups are named <name>_<quantity>
    effort: str
    flow: str
    position: str | None = None


@dataclass(frozen=True)
class Quantity:
    """A single-quantity OSP-IS variable group (e.g. the Voltage a controller commands)."""

    kind: str        # an OSP-IS quantity, e.g. "Voltage"
    name: str
    variables: tuple[str, ...]


@dataclass(frozen=True)
class DocumentedRun:
    """The FMU's reference run, in its documentation and its FMI cross-check files.

    input_rows: (time, value per input_names) in the cross-check input convention (linear
    interpolation; a repeated time is a step), Booleans as 0/1; the run ends at the last
    time (without inputs, at the default experiment's stop time). outputs: the variables to
    record (None: all outputs), every output_interval [s] (at least every step; None: the
    harness's default).
    """

    description: str = "Default experiment, inputs at their start values."
    input_names: tuple[str, ...] = ()
    input_rows: tuple[tuple[float, ...], ...] = ()
    outputs: tuple[str, ...] | None = None
    output_interval: float | None = None


def rest_to_rest_move(efforts: Mapping[str, tuple[float, str]], constants: Mapping[str, float],
                      outputs: tuple[str, ...], note: str = "",
                      stop_time: float = 5.0) -> DocumentedRun:
    """Each effort input (name -> (amplitude, unit)) at +amplitude over [0.5, 1.5) s and
    -amplitude over [1.5, 2.5) s, 0 otherwise (a rest-to-rest move of a balanced,
    frictionless joint); the constant inputs held; note ends the description."""
    names = (*efforts, *constants)
    levels = ((0.0, 0.5, 0.0), (0.5, 1.5, 1.0), (1.5, 2.5, -1.0), (2.5, stop_time, 0.0))
    rows = tuple((t, *(sign * a for a, _ in efforts.values()), *constants.values())
                 for start, end, sign in levels for t in (start, end))
    moved = " and ".join(f"{name} = {a} {unit}" for name, (a, unit) in efforts.items())
    return DocumentedRun(f"Rest-to-rest move: drive effort {moved} over 0.5-1.5 s, reversed "
                         f"over 1.5-2.5 s, then zero{note}.", names, rows, outputs)


Values = Mapping[str, Union[float, bool]]


@dataclass(frozen=True)
class Run:
    """Parameters and inputs set before initialisation and held for duration [s]."""

    parameters: Values = field(default_factory=dict)
    inputs: Values = field(default_factory=dict)
    duration: float = 1.0


@dataclass(frozen=True)
class Registration:
    """An FMU of fmu_src as the harness knows it (module docstring).

    physics, ledger and monolithic_reference are for mechanisms (physics not None).
    """

    # what the documentation and the cross-check show
    reference_run: DocumentedRun = DocumentedRun()
    # OSP-IS variable groups; a mechanism's joints in the master's order, each with position
    ports: tuple[Port | Quantity, ...] = ()
    # Real parameters and inputs that move every output: the native C host's run, compared
    # with FMPy's (tests/test_native_host.py)
    moving_run: Run = Run()
    # states where every declared input dependency of an output acts, reached by holding
    # the run's inputs (tests/test_output_dependencies.py); and parameters that give every
    # initial dependency something to act on
    dependency_probes: tuple[Run, ...] = ()
    initial_parameters: Values = field(default_factory=dict)
    physics: Any = None  # the mechanism's Physics module
    # the energy ledger: output -> sign; the signed sum is constant (docs/energy_ledger.md)
    ledger: Mapping[str, int] = field(default_factory=dict)
    # the monolithic reference (harness.engines.reference) can solve it as one ODE
    monolithic_reference: bool = True
    # plot panels after the joints' tracking panels: (title, unit, names of its inputs or
    # outputs; a one-link mechanism's are `one_link_panels`), one quantity in one unit per
    # panel; the panels of one title are one panel in a figure of several models' variants,
    # a line style per name in order
    plot_panels: tuple[tuple[str, str, tuple[str, ...]], ...] = ()
    # outputs a result summary reports at the end of a run (an adjusting actuator's work)
    summary_outputs: tuple[str, ...] = ()

    def joints(self) -> tuple[Port, ...]:
        """The mechanism's joints: its ports with a position, in the master's order."""
        return tuple(p for p in self.ports if isinstance(p, Port) and p.position is not None)
