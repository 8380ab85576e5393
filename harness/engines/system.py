"""The system of a scenario variant as FMUs (`describe`): its FMUs, parameters and
connections, and the ECCO settings of a run with ECCO; and the RunResult of such a system's
run from the values of its components (`system_result`), shared by the engines that run it
(`harness.engines.libcosim`, `harness.engines.fmpy_ssp`).

The system, per joint (a one-joint scenario such as franchetti2021):

    sequencer (ScenarioSequencer) --theta_ref--> controller (PositionController) --V--> drive
    (DcMotorDrive) --tau_drive--> mechanism (the variant's model) --theta--> controller,
    --omega--> drive; sequencer --payload, locks, ...--> mechanism.

With several joints (demian2022) each joint has its own controller and drive, named
`controller_<joint>` and `drive_<joint>`, wired to that joint's position, speed and effort.
The ScenarioSequencer FMU plays the scenario it was built for: build/fmus' one when it plays
the scenario (franchetti2021 by default), else one built for the scenario into
build/system/<scenario>/fmus/.

Its parameters are the run plan's (`harness.engines.plan`): the mechanism's scenario and
variant parameters, and per joint the drive's model, PID gains and equilibrium start as the
controller's and drive's FMU parameters (`DrivePlan.fmu_parameters`), bound in the SSP's
SystemStructure.ssd (inline ssv:ParameterSet per component) and as InitialValues in
OspSystemStructure.xml (`harness.engines.writers`).

The system's masters step every FMU in parallel (Jacobi) at the fixed step: each connection
passes a value with one step of delay, where the FMPy master's loop (controller, motor,
mechanism in turn) has none. The loop thus carries two more steps of delay; at 1 ms that
changes the drive energies by less than the tolerances of tests/test_system.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness import scenarios
from harness.drive.motor import start_currents
from harness.drive.trace import DriveTrace
from harness.engines.plan import RunPlan, enabled_steps
from harness.engines.result import RECORD_INTERVAL, RunResult, assemble, recorded_points, suffix
from harness.engines.settings import EccoSettings
from harness.fmu import build as fmu_build
from harness.fmu import osp
from harness.scenarios import losses

# the component names of the system's FMUs
SEQUENCER, CONTROLLER, DRIVE, MECHANISM = "sequencer", "controller", "drive", "mechanism"
Value = float | bool | int

SYSTEM_DIR = fmu_build.DEFAULT_DEST.parent / "system"


@dataclass(frozen=True)
class System:
    """A planned run as FMUs: components (name -> model and parameters), the FMU of each
    model, and connections (source component, output, destination component, input)."""

    plan: RunPlan
    models: dict[str, str]
    parameters: dict[str, dict[str, Value]]
    connections: tuple[tuple[str, str, str, str], ...]
    fmus: dict[str, Path]
    ecco: EccoSettings | None = None   # None: libcosim's fixed step

    @property
    def scenario(self) -> scenarios.Scenario:
        return self.plan.scenario

    @property
    def step_size(self) -> float:
        """The fixed step [s], or ECCO's first."""
        return self.plan.step_size

    @property
    def name(self) -> str:
        return f"{self.scenario.name}_{self.plan.variant.name}"

    @property
    def bonds(self) -> list[osp.PowerBond]:
        """The power bonds between the drives and the mechanism (osp.power_bonds)."""
        return osp.power_bonds(self.models, self.connections)


def controller(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's controller: `controller` or `controller_<joint>`."""
    return CONTROLLER + suffix(scenario, joint)


def drive(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's drive: `drive` or `drive_<joint>`."""
    return DRIVE + suffix(scenario, joint)


def describe(plan: RunPlan, ecco: EccoSettings | None = None) -> System:
    """The system of FMUs for a planned run (the ScenarioSequencer built for the scenario if
    build/fmus' one plays another). A variant's own joints get their controllers and drives
    too, each drive switched on and off by the sequencer (`<position>_enable`). ecco: run it
    with ECCO (the plan's step is then its first step), else at the fixed step."""
    scenario, variant = plan.scenario, plan.variant
    inputs = {name: signal[0] for name, signal in plan.inputs.items()}
    # the variant by number: SSP tools read Integer parameters, not all read Strings
    number = list(scenario.variants).index(variant.name) + 1
    parameters: dict[str, dict[str, Value]] = {SEQUENCER: {"variant_number": number}}
    models = {SEQUENCER: fmu_build.SEQUENCER}
    connections = []
    for planned in plan.drives:
        joint = planned.joint
        control, power = controller(scenario, joint), drive(scenario, joint)
        models |= {control: "PositionController", power: "DcMotorDrive"}
        parameters[control], parameters[power] = planned.fmu_parameters()
        connections += [(SEQUENCER, f"{joint.position}_ref", control, "theta_ref"),
                        (MECHANISM, joint.position, control, "theta"),
                        (control, "V", power, "V"),
                        (MECHANISM, joint.speed, power, "omega"),
                        (power, "tau_drive", MECHANISM, joint.effort),
                        (SEQUENCER, f"{joint.position}_enable", control, "enable"),
                        (SEQUENCER, f"{joint.position}_enable", power, "enable")]
    models[MECHANISM] = plan.model
    parameters[MECHANISM] = plan.parameters
    connections += [(SEQUENCER, name, MECHANISM, name) for name in inputs]
    fmus = {m: fmu_build.locate(m) for m in set(models.values()) - {fmu_build.SEQUENCER}}
    fmus[fmu_build.SEQUENCER] = sequencer_fmu(scenario)
    return System(plan, models, parameters, tuple(connections), fmus, ecco)


def sequencer_fmu(scenario: scenarios.Scenario) -> Path:
    """A ScenarioSequencer FMU that plays the scenario as its loss set runs it: build/fmus'
    one where that plays the shipped file the scenario was loaded from, else one built into
    build/system/<scenario>/<loss set>/fmus/ from the file `losses.played_file` gives,
    rebuilt when its inputs change (`fmu_build.fmu_path`): the one FMU a system builds, as
    it is part of the system's description."""
    from fmpy import read_model_description

    default = fmu_build.locate(fmu_build.SEQUENCER)
    shipped = (scenarios.SCENARIO_DIR / f"{scenario.name}.toml").resolve()
    plays = f"plays scenario {scenario.name} " in (
        read_model_description(str(default)).description or "")
    if plays and scenario.loss_set == "ideal" and scenario.file == shipped:
        return default
    folder = SYSTEM_DIR / scenario.name / scenario.loss_set
    return fmu_build.fmu_path(fmu_build.SEQUENCER, folder / "fmus",
                              sequencer_scenario=losses.played_file(scenario, folder))


def model_variables(system: System) -> dict[str, dict]:
    """Model variables by component and name, from the built FMUs."""
    from fmpy import read_model_description
    return {component: {v.name: v for v in
                        read_model_description(system.fmus[model]).modelVariables}
            for component, model in system.models.items()}


def recorded_every(system: System) -> int:
    """The communication points between two recorded rows of a fixed-step run."""
    return max(1, round(RECORD_INTERVAL / system.step_size))


def recorded_variables(system: System, variables: dict[str, dict]) -> dict[str, list[str]]:
    """Per component, the variables a run reads: as the harness records them (the
    mechanism's outputs and scenario inputs, the references) plus the drives' signals."""
    scenario = system.scenario
    fed = [end for start, _, component, end in system.connections
           if start == SEQUENCER and component == MECHANISM]
    mechanism = [n for n, v in variables[MECHANISM].items() if v.causality == "output"]
    return {SEQUENCER: [f"{joint.position}_ref" for joint in scenario.joints],
            **{controller(scenario, joint): ["V"] for joint in scenario.joints},
            **{drive(scenario, joint): ["i", "tau_drive"] for joint in scenario.joints},
            MECHANISM: mechanism + fed}


def system_result(system: System, frame: pd.DataFrame, booleans: pd.DataFrame,
            messages: list[str], times: np.ndarray | None = None) -> RunResult:
    """A RunResult from every communication point's values (frame, row k at t_k, columns
    `component.variable`) and the Boolean values at the recording points; times: the
    communication points [s] of a run with variable steps (ECCO), whose Booleans are given
    at every point, None for the fixed step."""
    scenario = system.scenario
    variables = model_variables(system)
    record = recorded_variables(system, variables)
    step: float | np.ndarray = system.step_size if times is None else np.diff(times)
    every = recorded_points(
        np.arange(len(frame)) * system.step_size if times is None else times, step)
    mechanism_columns = [n for n in record[MECHANISM] if f"{MECHANISM}.{n}" in frame
                         or n in booleans]
    rows = frame.iloc[every]
    if times is not None:
        booleans = booleans.iloc[every]
    table = pd.DataFrame({n: (booleans[n].to_numpy()[:len(rows)] if n in booleans
                              else rows[f"{MECHANISM}.{n}"].to_numpy())
                          for n in mechanism_columns})
    # Jacobi: over step k the drive holds the controller's V(t_k) and the speed omega(t_k),
    # and the mechanism gets the drive's effort of step k - 1, i.e. its output at t_k
    traces = []
    point_times = np.arange(len(frame)) * system.step_size if times is None else times
    for j, planned in enumerate(system.plan.drives):
        joint, motor = planned.joint, planned.motor
        control, power = controller(scenario, joint), drive(scenario, joint)
        voltage = frame[f"{control}.V"].to_numpy()
        speed = frame[f"{MECHANISM}.{joint.speed}"].to_numpy()
        current = frame[f"{power}.i"].to_numpy()[1:]
        enabled = enabled_steps(scenario, j, point_times)
        traces.append(DriveTrace(
            joint, motor, step, voltage[:-1], current,
            frame[f"{power}.tau_drive"].to_numpy()[:-1],
            start_currents(motor, step, voltage[:-1], speed[:-1], current, enabled),
            frame[f"{MECHANISM}.{joint.position}"].to_numpy(), speed,
            frame[f"{SEQUENCER}.{joint.position}_ref"].to_numpy(), enabled))
    return assemble(system.plan, table, traces, messages)
