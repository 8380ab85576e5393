"""FMI 2.0 Co-Simulation slave that plays a task scenario: the joints' references and the
inputs the scenario drives, as outputs to connect to a mechanism FMU and its controllers.

A thin layer over `scenario` (this folder's scenario.py), the definitions the harness uses. The
scenario is the file embedded at build time as the module `sequencer_scenario` of this folder in
the FMU's resources, generated into the build's staging folder (`harness.fmu.build`):
franchetti2021 by default, or any scenario file with `python -m harness build-fmus
--sequencer-scenario FILE`. The module also holds the unit of each Real input, which the
harness reads from the mechanisms the scenario drives, so the slave runs only with a resources
folder that holds it (inside an FMU, or one the harness stages). The String
parameter `variant` picks one of its variants by name, or the Integer parameter `variant_number`
by its position in the scenario file (1, 2, ...; 0, the default, leaves the choice to
`variant`), for hosts that cannot set String parameters (OMSimulator reads no String parameter
binding of an SSP). Each instance reads the module from its own resources folder by path rather
than importing it by name: pythonfmu runs every FMU of a process in one interpreter, which
caches modules by name, so two sequencers playing different scenarios would otherwise both play
the one imported first.

Outputs at a communication point t (after fmi2DoStep(t - h, h); at the start time after
initialisation), with t on the scenario's clock (t = 0 is its start):
- `<position>_ref` per joint of any variant [rad or m]: the quintic reference
  (`Scenario.reference_at` of the scenario resolved for the variant, `Scenario.for_variant`);
  0 for a variant's own joint when another variant is played;
- `<position>_enable` per joint of any variant: whether the joint's drive is on over the step
  from t (`Scenario.drive_enabled`: a joint that rests when holding is off in the phases
  that hold it); true for a joint the variant played does not drive;
- every input that a phase or a variant of the scenario sets (`Scenario.inputs_at`), Real or
  Boolean as in the file; an input the chosen variant drops stays at 0 or false.
A t less than `scenario.STEP_TIME_TOLERANCE` h before a phase start counts as that start, so
hosts that add up their time (t += h) switch at the same step as those that compute it.
"""

from __future__ import annotations

import runpy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fmu_src.fmi.slave import ModelSlave, VariableInfo
from fmu_src.fmi.vocabulary import DefaultExperiment, ValueType
from fmu_src.mechanism import DocumentedRun, Registration, Run
from fmu_src.units.sequencer import scenario as core
from fmu_src.units.sequencer import scenario_format


@dataclass(frozen=True)
class NoParameters:
    """The sequencer has no Real or Boolean parameters (`variant` is a String,
    `variant_number` an Integer)."""


# where the embedded scenario's module is in an FMU's resources
EMBEDDED_MODULE = ("fmu_src", "units", "sequencer", "sequencer_scenario.py")


def embedded_scenario(resources: str | None) -> tuple[core.Scenario, dict[str, str]]:
    """The scenario embedded in the FMU with this resources folder and the unit of each Real
    input it drives (its INPUT_UNITS, written by the harness from the mechanisms' inputs);
    ValueError if the folder (None: none) holds no embedded module."""
    path = None if resources is None else Path(resources, *EMBEDDED_MODULE)
    if path is None or not path.is_file():
        raise ValueError(f"no scenario module {'/'.join(EMBEDDED_MODULE)} in the resources "
                         f"folder {resources}: the sequencer plays the scenario its build "
                         "embeds (harness.fmu.build)")
    module = runpy.run_path(str(path))  # not cached in sys.modules (see the docstring)
    return scenario_format.parse(module["DATA"], f"{module['NAME']}.toml"), module["INPUT_UNITS"]


def scenario_inputs(scenario: core.Scenario) -> dict[str, bool | float]:
    """Every input any variant of the scenario drives, with its value before the start."""
    inputs: dict[str, bool | float] = {}
    for variant in scenario.variants.values():
        for name, (_, end, _) in scenario.input_segments(variant)[0].items():
            inputs.setdefault(name, False if isinstance(end, bool) else 0.0)
    return inputs


def input_units(scenario: core.Scenario, units: dict[str, str]) -> dict[str, str | None]:
    """The unit of each input the scenario drives: None for a Boolean, from units for a Real
    one."""
    return {name: None if isinstance(value, bool) else units[name]
            for name, value in scenario_inputs(scenario).items()}


class ScenarioSequencer(ModelSlave):
    """Plays one task scenario: joint references and mechanism inputs over time."""

    parameters_type = NoParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.scenario, units = embedded_scenario(kwargs.get("resources"))
        scenario = self.scenario
        self.default_experiment = DefaultExperiment(start_time=0.0,
                                                    stop_time=scenario.duration, step_size=1e-3)
        self.description = (f"Scenario sequencer: plays scenario {scenario.name} "
                            f"({scenario.description})")
        choices = ", ".join(scenario.variants)
        self.variant = next(iter(scenario.variants))
        description = f"Variant of scenario {scenario.name} to play: one of {choices}"
        self.add_parameter("variant", ValueType.string, VariableInfo(None, description))
        self.variant_number = 0
        numbers = ", ".join(f"{n} = {name}" for n, name in enumerate(scenario.variants, 1))
        description = (f"Variant of scenario {scenario.name} by number: {numbers}; 0 plays "
                       "the variant named by `variant`")
        self.add_parameter("variant_number", ValueType.integer, VariableInfo(None, description))
        # the joints of every variant: the scenario's, then variants' own (0 where the
        # variant played does not drive them)
        joints = {j.name: j for v in scenario.variants.values()
                  for j in scenario.for_variant(v).joints}
        self.reference_names = {name: f"{j.position}_ref" for name, j in joints.items()}
        self.enable_names = {name: f"{j.position}_enable" for name, j in joints.items()}
        for name, joint in joints.items():
            self.add_output(self.reference_names[name], joint.unit, "Reference position of "
                            f"joint {name} (quintic between the phases' targets)")
            self.add_output(self.enable_names[name], None, f"The drive of joint {name} is on "
                            "over the next step (off while a joint that holds by itself holds)")
        self.played = scenario                # resolved for the variant played
        self.defaults = scenario_inputs(scenario)
        for name, unit in input_units(scenario, units).items():
            self.add_output(name, unit, f"Scenario input {name} for the mechanism")
        self.start_time = 0.0
        self.step_start = 0.0
        self.segments: list[dict[str, tuple]] = []

    def chosen_variant(self) -> core.Variant:
        """The variant `variant_number` picks, or else the one `variant` names; ValueError
        naming the allowed range or the choices."""
        names = list(self.scenario.variants)
        number = int(self.variant_number)
        if not 0 <= number <= len(names):
            raise ValueError(f"variant_number = {number} is outside [0, {len(names)}] (0: "
                             "the variant named by `variant`)")
        return self.scenario.variant(names[number - 1] if number else str(self.variant))

    def validate(self, params: NoParameters) -> None:
        self.chosen_variant()

    def setup_experiment(self, start_time: float, stop_time: float | None,
                         tolerance: float | None) -> None:
        self.start_time = start_time

    def initialise(self, params: NoParameters) -> None:
        self.play(self.chosen_variant())
        self.show(self.start_time)

    def play(self, variant: core.Variant) -> None:
        """Prepare to play a variant: its joints' references and its input segments, both of
        the phases it performs (`Scenario.for_variant`), so that a phase index is the same in
        both."""
        self.played = self.scenario.for_variant(variant)
        self.segments = self.played.input_segments(variant)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.step_start = current_time
        return super().do_step(current_time, step_size)

    def step(self, dt: float) -> None:
        self.show(self.step_start + dt, core.STEP_TIME_TOLERANCE * dt)

    def show(self, time: float, tolerance: float = 0.0) -> None:
        """Set the outputs to the scenario's values at time [s]; a time within tolerance [s]
        before a phase start counts as that start."""
        played = self.played
        references = dict(zip((j.name for j in played.joints),
                              played.reference_at(time, tolerance)))
        self.__dict__.update({output: references.get(name, 0.0)
                              for name, output in self.reference_names.items()})
        phase = min(max(played._phase_at(time, tolerance), 0), len(played.phases) - 1)
        enabled = {joint.name: played.drive_enabled(j)[phase]
                   for j, joint in enumerate(played.joints)}
        self.__dict__.update({output: enabled.get(name, True)
                              for name, output in self.enable_names.items()})
        self.__dict__.update({**self.defaults,
                              **played.inputs_at(time, self.segments, tolerance)})

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        self.play(self.chosen_variant())


REGISTRATION = Registration(
    reference_run=DocumentedRun(
        "The embedded scenario over its default experiment (its duration), played with the "
        "default variant (the start value of `variant`); the sequencer has no inputs. "
        "Recorded every 1/8 s (a binary fraction: the phase boundaries of the shipped "
        "scenarios fall on it) and on both sides of every switch of a Boolean output.",
        output_interval=0.125),
    moving_run=Run(duration=5.0),  # 1 s into the move of phase II
    dependency_probes=(Run(duration=5.0),),  # no inputs: a function of time alone
)
