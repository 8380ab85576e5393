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

Its parameters are the harness's (`harness.engines.setup`): the mechanism's scenario and
variant parameters, the motor parameters, the PID gains designed for the joint and the
equilibrium start (motor current and integrator holding the static load at t = 0), bound in
the SSP's SystemStructure.ssd (inline ssv:ParameterSet per component) and as InitialValues in
OspSystemStructure.xml (`harness.engines.writers`).

The system's masters step every FMU in parallel (Jacobi) at the fixed step: each connection
passes a value with one step of delay, where the FMPy master's loop (controller, motor,
mechanism in turn) has none. The loop thus carries two more steps of delay; at 1 ms that
changes the drive energies by less than the tolerances of tests/test_system.py.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from fmu_src.units.drive.dc_motor import armature_voltage
from harness import scenarios
from harness.drive.controller import ControllerDesign, PIDGains
from harness.drive.motor import JointDrive, start_currents
from harness.drive.trace import DriveTrace
from harness.engines import DEFAULT_STEP
from harness.engines.result import RECORD_INTERVAL, RunResult, assemble, recorded_points, suffix
from harness.engines.setup import Drives, enabled_steps, joint_drive, joint_drives, run_parameters
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu import osp
from harness.fmu.loader import CoSimFMU

# the component names of the system's FMUs
SEQUENCER, CONTROLLER, DRIVE, MECHANISM = "sequencer", "controller", "drive", "mechanism"
Value = float | bool | int

SYSTEM_DIR = fmu_build.DEFAULT_DEST.parent / "system"


@dataclass(frozen=True)
class EccoSettings:
    """libcosim's ECCO algorithm (Sadjina et al. 2017): after each step it takes the power
    each side of every power bond sees (its held input times its new output), and sizes the
    next step with a PI controller on the bonds' energy residuals |P_a - P_b| h, scaled by
    abs_tolerance + rel_tolerance max|P_a - P_b| h; no step is rejected. Times in s,
    tolerances in J."""

    abs_tolerance: float = 1e-7
    rel_tolerance: float = 1e-4
    min_step: float = 1e-4
    max_step: float = 1e-2
    safety_factor: float = 0.8
    # the factor the step may change by at once, min and max (libcosim's own test data)
    min_change_rate: float = 0.2
    max_change_rate: float = 1.5
    p_gain: float = 0.2
    i_gain: float = 0.15

    def check(self) -> None:
        """UserError naming the first setting outside its range."""
        for name, value in asdict(self).items():
            if not (value > 0.0 and np.isfinite(value)):
                raise UserError(f"ECCO {name} = {value} is outside (0, inf)")
        if self.min_step > self.max_step:
            raise UserError(f"ECCO min_step = {self.min_step} s exceeds max_step = "
                            f"{self.max_step} s")
        if self.min_change_rate > 1.0 or self.max_change_rate < 1.0:
            raise UserError(f"ECCO change rates [{self.min_change_rate}, "
                            f"{self.max_change_rate}] must hold 1")

    def osp_elements(self, initial_step: float) -> dict[str, float]:
        """The EccoConfiguration elements of an OspSystemStructure.xml, by tag."""
        return {"SafetyFactor": self.safety_factor,
                "StepSize": min(max(initial_step, self.min_step), self.max_step),
                "MinimumStepSize": self.min_step, "MaximumStepSize": self.max_step,
                "MinimumChangeRate": self.min_change_rate,
                "MaximumChangeRate": self.max_change_rate,
                "ProportionalGain": self.p_gain, "IntegralGain": self.i_gain,
                "RelativeTolerance": self.rel_tolerance,
                "AbsoluteTolerance": self.abs_tolerance}


@dataclass(frozen=True)
class System:
    """A scenario variant as FMUs: components (name -> model and parameters), the FMU of
    each model, and connections (source component, output, destination component, input)."""

    scenario: scenarios.Scenario
    variant: scenarios.Variant
    step_size: float
    models: dict[str, str]
    parameters: dict[str, dict[str, Value]]
    connections: tuple[tuple[str, str, str, str], ...]
    fmus: dict[str, Path]
    ecco: EccoSettings | None = None   # None: libcosim's fixed step
    drives: tuple[JointDrive, ...] = ()  # each joint's drive, in the scenario's joint order

    @property
    def name(self) -> str:
        return f"{self.scenario.name}_{self.variant.name}"

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


def describe(scenario: scenarios.Scenario, variant: scenarios.Variant,
             step_size: float = DEFAULT_STEP,
             design: ControllerDesign = ControllerDesign(),
             ecco: EccoSettings | None = None, drives: Drives = None) -> System:
    """The system of FMUs for a variant, with the harness's parameters and start (the
    ScenarioSequencer built for the scenario if build/fmus' one plays another). A variant's
    own joints get their controllers and drives too (`Scenario.for_variant`), each drive
    switched on and off by the sequencer (`<position>_enable`). ecco: run it with ECCO
    (step_size is then its first step), else at the fixed step. drives: each joint's drive by
    name, else the legacy drives (`harness.engines.setup.joint_drives`)."""
    scenario = scenario.for_variant(variant)
    joint_drive_set = joint_drives(scenario, drives=drives)
    drive_motors = [drive.parameters for drive in joint_drive_set]
    model = variant.model or scenario.model
    mechanism_parameters = run_parameters(scenario, variant, drive_motors)
    inputs = {name: signal[0] for name, signal in
              scenario.inputs(np.zeros(1), variant).items()}
    # the variant by number: SSP tools read Integer parameters, not all read Strings
    number = list(scenario.variants).index(variant.name) + 1
    parameters: dict[str, dict[str, Value]] = {SEQUENCER: {"variant_number": number}}
    models = {SEQUENCER: fmu_build.SEQUENCER}
    connections = []
    with CoSimFMU(fmu_build.locate(model), f"{scenario.name}.{variant.name}.design") as fmu:
        fmu.set(inputs)
        fmu.initialize(mechanism_parameters, stop_time=scenario.duration)
        for j, (joint, motor) in enumerate(zip(scenario.joints, drive_motors, strict=True)):
            values = fmu.get([joint.inertia, joint.friction, joint.static_output])
            gains, hold_current = joint_drive(values, joint, motor, design)
            if not scenario.drive_enabled(j)[0]:  # off from the start: nothing to hold
                hold_current = 0.0
            control, power = controller(scenario, joint), drive(scenario, joint)
            models |= {control: "PositionController", power: "DcMotorDrive"}
            parameters[control] = {**gains._asdict(), "V_supply": motor.V_supply,
                                   "integral0": armature_voltage(motor, hold_current, 0.0)}
            parameters[power] = {**asdict(motor), "i0": hold_current}
            connections += [(SEQUENCER, f"{joint.position}_ref", control, "theta_ref"),
                            (MECHANISM, joint.position, control, "theta"),
                            (control, "V", power, "V"),
                            (MECHANISM, joint.speed, power, "omega"),
                            (power, "tau_drive", MECHANISM, joint.effort),
                            (SEQUENCER, f"{joint.position}_enable", control, "enable"),
                            (SEQUENCER, f"{joint.position}_enable", power, "enable")]
    models[MECHANISM] = model
    parameters[MECHANISM] = mechanism_parameters
    connections += [(SEQUENCER, name, MECHANISM, name) for name in inputs]
    fmus = {m: fmu_build.locate(m) for m in set(models.values()) - {fmu_build.SEQUENCER}}
    fmus[fmu_build.SEQUENCER] = sequencer_fmu(scenario)
    return System(scenario, variant, step_size, models, parameters, tuple(connections), fmus,
                  ecco, tuple(joint_drive_set))


def _plays(fmu: Path, scenario: scenarios.Scenario) -> bool:
    """Whether a ScenarioSequencer FMU plays this scenario (its description names it)."""
    from fmpy import read_model_description
    return f"plays scenario {scenario.name} " in (read_model_description(fmu).description or "")


def sequencer_fmu(scenario: scenarios.Scenario) -> Path:
    """A ScenarioSequencer FMU that plays the scenario: build/fmus' one if it does, else one
    built for the (shipped) scenario into build/system/<scenario>/fmus/, rebuilt when its
    inputs change (`fmu_build.fmu_path`): the one FMU a system builds, as it is part of the
    system's description."""
    default = fmu_build.locate(fmu_build.SEQUENCER)
    if _plays(default, scenario):
        return default
    source = scenarios.scenario_file(scenario.name)  # ValueError naming the known scenarios
    return fmu_build.fmu_path(fmu_build.SEQUENCER, SYSTEM_DIR / scenario.name / "fmus",
                              sequencer_scenario=source)


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
    traces, gains = [], {}
    point_times = np.arange(len(frame)) * system.step_size if times is None else times
    for j, (joint, joint_drive_) in enumerate(zip(scenario.joints, system.drives, strict=True)):
        motor = joint_drive_.parameters
        control, power = controller(scenario, joint), drive(scenario, joint)
        voltage = frame[f"{control}.V"].to_numpy()
        speed = frame[f"{MECHANISM}.{joint.speed}"].to_numpy()
        current = frame[f"{power}.i"].to_numpy()[1:]
        enabled = np.array(enabled_steps(scenario, j, point_times))
        traces.append(DriveTrace(
            joint, motor, step, voltage[:-1], current,
            frame[f"{power}.tau_drive"].to_numpy()[:-1],
            start_currents(motor, step, voltage[:-1], speed[:-1], current, enabled),
            frame[f"{MECHANISM}.{joint.position}"].to_numpy(), speed,
            frame[f"{SEQUENCER}.{joint.position}_ref"].to_numpy(), enabled))
        gains[joint.name] = PIDGains(*(float(system.parameters[control][n])
                                       for n in PIDGains._fields))
    return assemble(scenario, system.variant, system.models[MECHANISM], table, traces,
                    gains, dict(system.parameters[MECHANISM]), messages,
                    drives=list(system.drives))
