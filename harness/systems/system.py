"""`python -m harness system`: the task as a system of FMUs, described in SSP and OSP and run
by DNV's libcosim or by FMPy's SSP runner, with results in the harness's format.

The system of a scenario variant, per joint (a one-joint scenario such as franchetti2021):

    sequencer (ScenarioSequencer) --theta_ref--> controller (PositionController) --V--> drive
    (DcMotorDrive) --tau_drive--> mechanism (the variant's model) --theta--> controller,
    --omega--> drive; sequencer --payload, locks, ...--> mechanism.

With several joints (demian2022) each joint has its own controller and drive, named
`controller_<joint>` and `drive_<joint>`, wired to that joint's position, speed and effort.
The ScenarioSequencer FMU plays the scenario it was built for: build/fmus' one when it plays
the scenario (franchetti2021 by default), else one built for the scenario into
build/system/<scenario>/fmus/.

Its parameters are the harness's: the mechanism's scenario and variant parameters, the motor
defaults (harness.run.drive), the PID gains designed for the joint (harness.run.controller) and the
equilibrium start (motor current and integrator holding the static load at t = 0), bound in
the SSP's SystemStructure.ssd (inline ssv:ParameterSet per component) and as InitialValues
in OspSystemStructure.xml.

Both masters step every FMU in parallel (Jacobi) at the fixed step: each connection passes a
value with one step of delay, where the harness's loop (controller, motor, mechanism in
turn) has none. The loop thus carries two more steps of delay; at 1 ms that changes the
drive energies by less than the tolerances of tests/test_system.py. With `--algorithm ecco`
libcosim's ECCO steps the same Jacobi exchange at a step it adapts to the energy residuals
of the power bonds between each drive and its joint (`EccoSettings`, `ecco_execution`,
docs/results.md#variable-steps-ecco).

FMPy 0.3.32's `simulate_ssp` (engine `fmpy-ssp`), compared with libcosim on this system:
- right: the connections, the fixed step, the Jacobi exchange;
- wrong, worked around here: it ignores the SSD's parameter bindings (they are passed as its
  `parameter_set` argument instead) and it reads Boolean literals as true whatever they say
  (values are passed as Python types). It cannot set String parameters either, which is one
  reason the sequencer's variant is bound by number (`variant_number`, an Integer), the
  other that OMSimulator reads no String binding;
- wrong, not worked around (it shows in the results): every connected input starts at 0.0
  instead of the source's start value, so in the first step the controller sees theta = 0
  and the mechanism gets tau_drive = 0; and the rows are stamped with the time at the start
  of the step although they hold the values at its end (corrected here when recording).
"""

from __future__ import annotations

import argparse
import shutil
import zipfile
from dataclasses import asdict, dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pandas as pd
from tqdm import tqdm

from fmu_src.units.drive.dc_motor import armature_voltage
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu import osp
from harness.fmu.loader import CoSimFMU
from harness.io import write_atomic
from harness.run import cosim, master, results
from harness.run import scenario_files as scenarios
from harness.run.controller import ControllerDesign, PIDGains
from harness.run.drive import DriveTrace, motors, start_currents

ENGINES = ("libcosim", "fmpy-ssp")
SEQUENCER, CONTROLLER, DRIVE, MECHANISM = "sequencer", "controller", "drive", "mechanism"
SYSTEM_DIR = fmu_build.DEFAULT_DEST.parent / "system"
# OMSimulator matches SSD elements by their qualified names: keep these prefixes
NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
      "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
      "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"}
# OMSimulator's fixed-step master ("oms-ma") needs tolerances although it steps no solver
OMS_TOLERANCE = 1e-4
OSP_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"
ECCO_CHUNK = 1000  # an ECCO run's steps between two reads of its time series
Value = float | bool | int
ALGORITHMS = ("fixed", "ecco")


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

    @property
    def name(self) -> str:
        return f"{self.scenario.name}_{self.variant.name}"

    @property
    def bonds(self) -> list[osp.PowerBond]:
        """The power bonds between the drives and the mechanism (osp.power_bonds)."""
        return osp.power_bonds(self.models, self.connections)


def controller(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's controller: `controller` or `controller_<joint>`."""
    return CONTROLLER + master.suffix(scenario, joint)


def drive(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's drive: `drive` or `drive_<joint>`."""
    return DRIVE + master.suffix(scenario, joint)


def describe(scenario: scenarios.Scenario, variant: scenarios.Variant,
             step_size: float = master.DEFAULT_STEP,
             design: ControllerDesign = ControllerDesign(),
             ecco: EccoSettings | None = None) -> System:
    """The system of FMUs for a variant, with the harness's parameters and start (the
    ScenarioSequencer built for the scenario if build/fmus' one plays another). A variant's
    own joints get their controllers and drives too (`Scenario.for_variant`). ecco: run it
    with ECCO (step_size is then its first step), else at the fixed step."""
    scenario = scenario.for_variant(variant)
    drive_motors = [motors()[joint.motor] for joint in scenario.joints]
    model = variant.model or scenario.model
    mechanism_parameters = master.run_parameters(scenario, variant, drive_motors)
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
        for joint, motor in zip(scenario.joints, drive_motors, strict=True):
            gains, hold_current = master.joint_drive(fmu, joint, motor, design)
            control, power = controller(scenario, joint), drive(scenario, joint)
            models |= {control: "PositionController", power: "DcMotorDrive"}
            parameters[control] = {**gains._asdict(), "V_supply": motor.V_supply,
                                   "integral0": armature_voltage(motor, hold_current, 0.0)}
            parameters[power] = {**asdict(motor), "i0": hold_current}
            connections += [(SEQUENCER, f"{joint.position}_ref", control, "theta_ref"),
                            (MECHANISM, joint.position, control, "theta"),
                            (control, "V", power, "V"),
                            (MECHANISM, joint.speed, power, "omega"),
                            (power, "tau_drive", MECHANISM, joint.effort)]
    models[MECHANISM] = model
    parameters[MECHANISM] = mechanism_parameters
    connections += [(SEQUENCER, name, MECHANISM, name) for name in inputs]
    fmus = {m: fmu_build.locate(m) for m in set(models.values()) - {fmu_build.SEQUENCER}}
    fmus[fmu_build.SEQUENCER] = sequencer_fmu(scenario)
    return System(scenario, variant, step_size, models, parameters, tuple(connections), fmus,
                  ecco)


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


# ---- system descriptions ------------------------------------------------------------------
def _model_variables(system: System) -> dict[str, dict]:
    """Model variables by component and name, from the built FMUs."""
    from fmpy import read_model_description
    return {component: {v.name: v for v in
                        read_model_description(system.fmus[model]).modelVariables}
            for component, model in system.models.items()}


def _bindings(system: System) -> dict[str, list[tuple[str, str, str]]]:
    """Per component, its parameters as (name, FMI type of the variable, literal)."""
    variables = _model_variables(system)
    return {component: [(name, variables[component][name].type,
                         str(value).lower() if isinstance(value, bool) else str(value))
                        for name, value in values.items()]
            for component, values in system.parameters.items()}


def ssd_tree(system: System) -> ET.ElementTree:
    """SystemStructure.ssd: components with connectors (every output, every connected
    input) and inline parameter bindings, connections, the system's OpenModelica annotation
    (OMSimulator's fixed-step master, without which OMSimulator 3.0 aborts) and a
    DefaultExperiment over the task [s], where OMSimulator's import reads the stop time (its
    command line overrides it with --stopTime: README), whose OSP annotation gives the fixed
    step (libcosim)."""
    for prefix, uri in NS.items():
        ET.register_namespace(prefix, uri)
    ssd, ssc, ssv, osp_, oms = (f"{{{NS[p]}}}" for p in ("ssd", "ssc", "ssv", "osp", "oms"))
    variables = _model_variables(system)
    bindings = _bindings(system)
    root = ET.Element(f"{ssd}SystemStructureDescription", version="1.0", name=system.name)
    root_system = ET.SubElement(root, f"{ssd}System", name=system.name,
                                description=system.variant.description or system.name)
    elements = ET.SubElement(root_system, f"{ssd}Elements")
    for component, model in system.models.items():
        element = ET.SubElement(elements, f"{ssd}Component", name=component,
                                type="application/x-fmu-sharedlibrary",
                                source=f"resources/{model}.fmu")
        connectors = ET.SubElement(element, f"{ssd}Connectors")
        ends = {(c, n) for a, b, c2, d in system.connections for c, n in ((a, b), (c2, d))}
        for name, variable in variables[component].items():
            if (component, name) in ends or variable.causality == "output":
                connector = ET.SubElement(connectors, f"{ssd}Connector", name=name,
                                          kind=variable.causality)
                ET.SubElement(connector, f"{ssc}{variable.type}")
        values = ET.SubElement(ET.SubElement(ET.SubElement(element, f"{ssd}ParameterBindings"),
                                             f"{ssd}ParameterBinding"), f"{ssd}ParameterValues")
        parameter_set = ET.SubElement(values, f"{ssv}ParameterSet", version="1.0",
                                      name=component)
        parameters = ET.SubElement(parameter_set, f"{ssv}Parameters")
        for name, type_name, literal in bindings[component]:
            parameter = ET.SubElement(parameters, f"{ssv}Parameter", name=name)
            ET.SubElement(parameter, f"{ssv}{type_name}", value=literal)
    connections = ET.SubElement(root_system, f"{ssd}Connections")
    for start, start_connector, end, end_connector in system.connections:
        ET.SubElement(connections, f"{ssd}Connection", startElement=start,
                      startConnector=start_connector, endElement=end,
                      endConnector=end_connector)
    annotation = ET.SubElement(ET.SubElement(root_system, f"{ssd}Annotations"),
                               f"{ssc}Annotation", type="org.openmodelica")
    information = ET.SubElement(ET.SubElement(annotation, f"{oms}Annotations"),
                                f"{oms}SimulationInformation")
    ET.SubElement(information, f"{oms}FixedStepMaster", description="oms-ma",
                  stepSize=str(system.step_size), absoluteTolerance=str(OMS_TOLERANCE),
                  relativeTolerance=str(OMS_TOLERANCE))
    experiment = ET.SubElement(root, f"{ssd}DefaultExperiment", startTime="0.0",
                               stopTime=str(system.scenario.duration))
    annotation = ET.SubElement(ET.SubElement(experiment, f"{ssd}Annotations"),
                               f"{ssc}Annotation", type="com.opensimulationplatform")
    ET.SubElement(ET.SubElement(annotation, f"{osp_}Algorithm"), f"{osp_}FixedStepAlgorithm",
                  baseStepSize=str(system.step_size))
    ET.indent(root)
    return ET.ElementTree(root)


def osp_tree(system: System, by_group: bool = True) -> ET.ElementTree:
    """OspSystemStructure.xml: the same simulators, initial values and connections; with
    by_group, the connections that join two FMUs' variable groups whole (the drive's shaft
    and the mechanism's joint, the controller's command and the drive's armature voltage;
    harness.fmu.osp) as one VariableGroupConnection each. With ECCO (system.ecco) the algorithm
    is `ecco` with its EccoConfiguration, and each power bond's two connections are
    VariableConnections named by the bond (powerBond) with their causalities, as libcosim's
    parser needs them (a VariableGroupConnection counts as one connection there)."""
    ET.register_namespace("", OSP_NS)
    ns = f"{{{OSP_NS}}}"
    root = ET.Element(f"{ns}OspSystemStructure", version="0.1")
    ET.SubElement(root, f"{ns}StartTime").text = "0.0"
    ET.SubElement(root, f"{ns}BaseStepSize").text = str(system.step_size)
    ET.SubElement(root, f"{ns}Algorithm").text = "fixedStep" if system.ecco is None else "ecco"
    simulators = ET.SubElement(root, f"{ns}Simulators")
    bindings = _bindings(system)
    for component, model in system.models.items():
        simulator = ET.SubElement(simulators, f"{ns}Simulator", name=component,
                                  source=f"{model}.fmu", stepSize=str(system.step_size))
        initial_values = ET.SubElement(simulator, f"{ns}InitialValues")
        for name, type_name, literal in bindings[component]:
            initial = ET.SubElement(initial_values, f"{ns}InitialValue", variable=name)
            ET.SubElement(initial, f"{ns}{type_name}", value=literal)
    connections = ET.SubElement(root, f"{ns}Connections")
    bonded = {} if system.ecco is None else {
        c: bond.name for bond in system.bonds
        for c in ((bond.sink, bond.sink_flow, bond.source, bond.source_flow),
                  (bond.source, bond.source_effort, bond.sink, bond.sink_effort))}
    groups = [g for g in (osp.group_connections(system.models, system.connections)
                          if by_group else []) if not bonded.keys() & set(g[-1])]
    grouped = {c for *_, covered in groups for c in covered}
    for start, start_variable, end, end_variable in system.connections:
        if (start, start_variable, end, end_variable) not in grouped:
            bond = bonded.get((start, start_variable, end, end_variable))
            connection = ET.SubElement(connections, f"{ns}VariableConnection",
                                       {} if bond is None else {"powerBond": bond})
            causality = {} if bond is None else {"causality": "output"}
            ET.SubElement(connection, f"{ns}Variable", simulator=start, name=start_variable,
                          **causality)
            causality = {} if bond is None else {"causality": "input"}
            ET.SubElement(connection, f"{ns}Variable", simulator=end, name=end_variable,
                          **causality)
    for a, group_a, b, group_b, _ in groups:
        connection = ET.SubElement(connections, f"{ns}VariableGroupConnection")
        ET.SubElement(connection, f"{ns}VariableGroup", simulator=a, name=group_a)
        ET.SubElement(connection, f"{ns}VariableGroup", simulator=b, name=group_b)
    if system.ecco is not None:
        configuration = ET.SubElement(root, f"{ns}EccoConfiguration")
        for tag, value in system.ecco.osp_elements(system.step_size).items():
            ET.SubElement(configuration, f"{ns}{tag}").text = repr(float(value))
    ET.indent(root)
    return ET.ElementTree(root)


def write_ssp(system: System, path: Path) -> Path:
    """The SSP archive: SystemStructure.ssd and the FMUs in resources/ (written atomically)."""
    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("SystemStructure.ssd",
                             ET.tostring(ssd_tree(system).getroot(), encoding="unicode",
                                         xml_declaration=True))
            for model in sorted(set(system.models.values())):
                archive.write(system.fmus[model], f"resources/{model}.fmu")
    return write_atomic(path, write)


def write_osp(system: System, folder: Path, by_group: bool = True) -> Path:
    """folder/OspSystemStructure.xml beside copies of the FMUs it names and their
    <Model>_OspModelDescription.xml (by_group: see osp_tree)."""
    folder.mkdir(parents=True, exist_ok=True)
    for model in set(system.models.values()):
        fmu = shutil.copy2(system.fmus[model], folder / f"{model}.fmu")
        osp.write_model_description(Path(fmu))
    return write_atomic(
        folder / "OspSystemStructure.xml",
        lambda tmp: osp_tree(system, by_group).write(tmp, encoding="utf-8",
                                                     xml_declaration=True))


# ---- running ------------------------------------------------------------------------------
def _recorded(system: System, variables: dict[str, dict]) -> dict[str, list[str]]:
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


def _result(system: System, frame: pd.DataFrame, booleans: pd.DataFrame,
            messages: list[str], times: np.ndarray | None = None) -> master.RunResult:
    """A RunResult from every communication point's values (frame, row k at t_k, columns
    `component.variable`) and the Boolean values at the recording points; times: the
    communication points [s] of a run with variable steps (ECCO), whose Booleans are given
    at every point, None for the fixed step."""
    scenario = system.scenario
    variables = _model_variables(system)
    record = _recorded(system, variables)
    step: float | np.ndarray = system.step_size if times is None else np.diff(times)
    every = master.recorded_points(
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
    for joint in scenario.joints:
        control, power = controller(scenario, joint), drive(scenario, joint)
        motor = motors()[joint.motor]
        voltage = frame[f"{control}.V"].to_numpy()
        speed = frame[f"{MECHANISM}.{joint.speed}"].to_numpy()
        current = frame[f"{power}.i"].to_numpy()[1:]
        traces.append(DriveTrace(
            joint, motor, step, voltage[:-1], current,
            frame[f"{power}.tau_drive"].to_numpy()[:-1],
            start_currents(motor, step, voltage[:-1], speed[:-1], current),
            frame[f"{MECHANISM}.{joint.position}"].to_numpy(), speed,
            frame[f"{SEQUENCER}.{joint.position}_ref"].to_numpy()))
        gains[joint.name] = PIDGains(*(float(system.parameters[control][n])
                                       for n in PIDGains._fields))
    return master.assemble(scenario, system.variant, system.models[MECHANISM], table, traces,
                           gains, dict(system.parameters[MECHANISM]), messages)


def _time_series(observer, slave: int, reference: int, steps: int, first: int = 0
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Samples of steps first..steps from a libcosim time-series observer, and their times
    [s].

    libcosimpy 0.0.6 trims its answer by the number of zero step numbers, which drops one
    real sample when step 0 is among them: ask again from where the answer stopped.
    """
    values: list[float] = []
    times: list[int] = []
    while len(values) <= steps - first:
        at = first + len(values)
        stamps, numbers, samples = observer.time_series_real_samples(
            slave, reference, at, steps + 2 - at)
        if not numbers or numbers[0] != at:
            raise RuntimeError(f"libcosim time series of variable {reference} ends at step "
                               f"{at} of {steps}")
        values.extend(samples)
        times.extend(stamps)
    count = steps + 1 - first
    return np.asarray(values[:count]), np.asarray(times[:count]) * 1e-9


def _ecco_steps(execution, system: System, series, last, index: dict[str, int],
                reals: list, bools: list) -> tuple[np.ndarray, pd.DataFrame, pd.DataFrame]:
    """Step an ECCO execution up to the first communication point at or after the task's
    end (libcosim does not shorten the last step); every point's time [s], Real values
    (drained from the time-series observer every ECCO_CHUNK steps) and Booleans (read from
    the last-value observer after each step; at t = 0, the scenario's)."""
    end = round(system.scenario.duration * 1e9)
    columns: dict[str, list[np.ndarray]] = {f"{c}.{v.name}": [] for c, v in reals}
    times: list[np.ndarray] = []
    boolean_rows = []
    steps = drained = 0
    while execution.status().current_time < end:
        if not execution.step(1):
            raise RuntimeError(f"libcosim (ECCO) failed in the step after t = "
                               f"{execution.status().current_time * 1e-9} s")
        steps += 1
        boolean_rows.append({v.name: bool(value) for (c, v) in bools
                             for value in last.last_boolean_values(index[c],
                                                                   [v.valueReference])})
        if steps - drained == ECCO_CHUNK or execution.status().current_time >= end:
            first = 0 if drained == 0 else drained + 1
            for c, v in reals:
                values, stamps = _time_series(series, index[c], v.valueReference, steps, first)
                columns[f"{c}.{v.name}"].append(values)
            times.append(stamps)
            drained = steps
    start = system.scenario.inputs(np.zeros(1), system.variant)
    first_row = {name: bool(start[name][0]) if name in start else value
                 for name, value in boolean_rows[0].items()}
    return (np.concatenate(times),
            pd.DataFrame({name: np.concatenate(parts) for name, parts in columns.items()}),
            pd.DataFrame([first_row, *boolean_rows]))


def ecco_execution(system: System) -> tuple[object, object]:
    """A libcosim execution of the system under ECCO, made through libcosimpy's API: its
    FMUs as local slaves with the system's parameters, its connections, and one power bond
    per `System.bonds` (source: the drive, its effort out and flow in; sink: the mechanism).
    Returns (execution, algorithm): the algorithm must live as long as the execution.

    Not from the OSP file: libcosim 0.0.6's parser refuses a file with more than one power
    bond (it checks the count of bonds against that of their names while still adding
    them), and active_relocation and demian2022 have two.
    """
    from libcosimpy.CosimAlgorithm import CosimAlgorithm, EccoParams
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimSlave import CosimLocalSlave

    settings = system.ecco
    elements = settings.osp_elements(system.step_size)
    algorithm = CosimAlgorithm.create_ecco_algorithm(EccoParams(
        safety_factor=settings.safety_factor, step_size=elements["StepSize"],
        min_step_size=settings.min_step, max_step_size=settings.max_step,
        min_change_rate=settings.min_change_rate, max_change_rate=settings.max_change_rate,
        abs_tolerance=settings.abs_tolerance, rel_tolerance=settings.rel_tolerance,
        p_gain=settings.p_gain, i_gain=settings.i_gain))
    execution = CosimExecution.from_algorithm(algorithm)
    variables = _model_variables(system)
    index = {component: execution.add_local_slave(CosimLocalSlave(
        str(system.fmus[model]), component)) for component, model in system.models.items()}
    setters = {"Real": execution.real_initial_value, "Integer": execution.integer_initial_value,
               "Boolean": execution.boolean_initial_value}
    for component, values in system.parameters.items():
        for name, value in values.items():
            variable = variables[component][name]
            setters[variable.type](index[component], variable.valueReference, value)
    connect = {"Real": execution.connect_real_variables,
               "Boolean": execution.connect_boolean_variables,
               "Integer": execution.connect_integer_variables}
    for start, output, end, input_name in system.connections:
        source = variables[start][output]
        if connect[source.type](index[start], source.valueReference, index[end],
                                variables[end][input_name].valueReference) != 0:
            raise RuntimeError(f"libcosim refused the connection {start}.{output} -> "
                               f"{end}.{input_name}")
    for bond in system.bonds:
        source, sink = variables[bond.source], variables[bond.sink]
        if algorithm.add_power_bond(
                index[bond.source], source[bond.source_effort].valueReference,
                source[bond.source_flow].valueReference, index[bond.sink],
                sink[bond.sink_flow].valueReference,
                sink[bond.sink_effort].valueReference) != 0:
            raise RuntimeError(f"libcosim refused the power bond {bond.name}")
    return execution, algorithm


def run_libcosim(system: System, source: Path | None = None) -> master.RunResult:
    """Run an OspSystemStructure.xml or an .ssp archive in libcosim at the fixed step, or
    an ECCO system (system.ecco; source None) through libcosimpy's API (`ecco_execution`).

    Real variables come from a time-series observer at every step; Booleans, which it does
    not record, from a last-value observer at the recording points (at t = 0, which that
    observer cannot see, the scenario's inputs and the values after the first step). The
    last-value observer also exposes every variable for reading, which libcosim's ECCO needs
    for the bonds' inputs (it reads them without exposing them).
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    nanoseconds = round(system.step_size * 1e9)
    algorithm = None
    if system.ecco is not None:
        execution, algorithm = ecco_execution(system)
    elif source.suffix == ".ssp":  # libcosim needs the step size given for an SSP
        execution = CosimExecution.from_ssp_file(str(source), step_size=nanoseconds)
    else:
        execution = CosimExecution.from_osp_config_file(str(source))
    steps = round(system.scenario.duration / system.step_size)
    every = max(1, round(master.RECORD_INTERVAL / system.step_size))
    series = CosimObserver.create_time_series(
        buffer_size=steps + 1 if system.ecco is None else ECCO_CHUNK + 2)
    last = CosimObserver.create_last_value()
    execution.add_observer(series)
    execution.add_observer(last)
    variables = _model_variables(system)
    index = {c: execution.slave_index_from_instance_name(c) for c in system.models}
    reals, bools = [], []
    for component, names in _recorded(system, variables).items():
        for name in names:
            variable = variables[component][name]
            (reals if variable.type == "Real" else bools).append((component, variable))
    for component, variable in reals:
        series.start_time_series(index[component], variable.valueReference,
                                 CosimVariableType.REAL)
    if system.ecco is not None:
        times, frame, booleans = _ecco_steps(execution, system, series, last, index, reals,
                                             bools)
        del execution, algorithm  # the execution first
        return _result(system, frame, booleans, [], times)
    boolean_rows = []
    for chunk in range(steps // every):
        if not execution.step(every):
            raise RuntimeError(f"libcosim failed in the steps after t = "
                               f"{chunk * every * system.step_size} s")
        boolean_rows.append({v.name: bool(value) for (c, v) in bools
                             for value in last.last_boolean_values(index[c],
                                                                   [v.valueReference])})
    if steps % every and not execution.step(steps % every):
        raise RuntimeError("libcosim failed in the last steps")
    start = system.scenario.inputs(np.zeros(1), system.variant)
    first = {name: bool(start[name][0]) if name in start else value
             for name, value in boolean_rows[0].items()} if boolean_rows else {}
    frame = pd.DataFrame({f"{c}.{v.name}": _time_series(series, index[c], v.valueReference,
                                                        steps)[0]
                          for c, v in reals})
    return _result(system, frame, pd.DataFrame([first, *boolean_rows]), [])


def run_fmpy_ssp(system: System, ssp: Path) -> master.RunResult:
    """Run the SSP archive with fmpy.ssp.simulate_ssp, which returns every connector after
    every step (stamped with the step's start time). It has no row for t = 0: that row is
    the start the system is built for (the scenario's initial position, inputs and
    reference; the drive holding i0) and the mechanism's other outputs after the first step.
    """
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet

    parameter_set = ParameterSet(name="bindings")
    for component, values in system.parameters.items():
        for name, value in values.items():
            parameter_set.parameters.append(Parameter(name=f"{component}.{name}", value=value))
    table = simulate_ssp(str(ssp), stop_time=system.scenario.duration,
                         step_size=system.step_size, parameter_set=parameter_set)
    frame = pd.DataFrame({name: table[name] for name in table.dtype.names[1:]})
    scenario = system.scenario
    start = frame.iloc[[0]].copy()
    start_inputs = scenario.inputs(np.zeros(1), system.variant)
    for joint, initial in zip(scenario.joints, scenario.initial_angle, strict=True):
        start[f"{MECHANISM}.{joint.position}"] = initial
        start[f"{SEQUENCER}.{joint.position}_ref"] = initial
        start[f"{controller(scenario, joint)}.V"] = 0.0   # FMPy: connected inputs start at 0
        start[f"{drive(scenario, joint)}.tau_drive"] = 0.0
    for name, signal in start_inputs.items():
        start[f"{MECHANISM}.{name}"] = signal[0]
    frame = pd.concat([start, frame], ignore_index=True)
    every = max(1, round(master.RECORD_INTERVAL / system.step_size))
    booleans = pd.DataFrame({c.split(".", 1)[1]: frame[c].iloc[::every].to_numpy()
                             for c in frame if c.startswith(f"{MECHANISM}.")
                             and frame[c].dtype == bool})
    return _result(system, frame, booleans, [])


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--engine", choices=ENGINES, default="libcosim",
                        help="the master that runs the system")
    parser.add_argument("--scenario", default="franchetti2021",
                        help=f"shipped scenario ({', '.join(scenarios.available())})")
    parser.add_argument("--variants", dest="variant", default="all", metavar="VARIANTS",
                        help="'all' or a comma-separated list (eps baselines are added)")
    parser.add_argument("--variant", dest="variant", default=argparse.SUPPRESS,
                        help=argparse.SUPPRESS)  # former spelling
    parser.add_argument("--step", type=float, default=master.DEFAULT_STEP,
                        help="communication step [s] (default 1e-3)")
    parser.add_argument("--source", choices=("osp", "ssp"), default="osp",
                        help="libcosim: run OspSystemStructure.xml (default) or the .ssp")
    parser.add_argument("--out", type=Path, help="results folder (default "
                        "build/system/<scenario>/<engine>, <engine>-ecco with ECCO); SSP "
                        "and OSP files go to build/system/<scenario>/")
    parser.add_argument("--algorithm", choices=ALGORITHMS, default="fixed",
                        help="libcosim: the fixed step (default) or ECCO, whose step adapts "
                        "to the power bonds' energy residuals (--step is its first step)")
    defaults = EccoSettings()
    for name, unit, meaning in ECCO_OPTIONS:
        parser.add_argument(f"--ecco-{name.replace('_', '-')}", dest=f"ecco_{name}",
                            type=float, default=getattr(defaults, name), metavar="X",
                            help=f"ECCO: {meaning} (default {getattr(defaults, name)}"
                            f"{' ' + unit if unit else ''})")


# the ECCO settings as options: (field of EccoSettings, unit, meaning)
ECCO_OPTIONS = (
    ("abs_tolerance", "J", "absolute tolerance on a bond's energy residual per step"),
    ("rel_tolerance", "", "relative tolerance on it"),
    ("min_step", "s", "smallest step"),
    ("max_step", "s", "largest step"),
    ("safety_factor", "", "safety factor of the step controller"),
    ("min_change_rate", "", "smallest factor between two steps"),
    ("max_change_rate", "", "largest factor between two steps"),
    ("p_gain", "", "proportional gain of the step controller"),
    ("i_gain", "", "integral gain of the step controller"),
)


def check_ecco(ecco: EccoSettings | None, engine: str, source: str) -> None:
    """UserError for ECCO settings out of range, or ECCO asked of another engine or source."""
    if ecco is None:
        return
    ecco.check()
    if engine != "libcosim":
        raise UserError("--algorithm ecco runs only in --engine libcosim")
    if source != "osp":
        raise UserError("--algorithm ecco runs from the OSP description (--source osp): "
                        "the SSP archive has no power bonds")


def run_system(scenario: scenarios.Scenario, variants: list[str], engine: str,
               step_size: float, out: Path, source: str = "osp",
               ecco: EccoSettings | None = None) -> list[master.RunResult]:
    """Describe, write and run each variant's system (with ECCO: libcosim only, from the
    OSP file); write results into out."""
    if engine not in ENGINES:
        raise UserError(f"engine {engine!r} is not one of {', '.join(ENGINES)}")
    check_ecco(ecco, engine, source)
    runs = []
    for name in tqdm(variants, desc=f"{scenario.name} system ({engine})", unit="variant"):
        system = describe(scenario, scenario.variant(name), step_size, ecco=ecco)
        files = SYSTEM_DIR / scenario.name
        ssp = write_ssp(system, files / f"{name}.ssp")
        if engine == "fmpy-ssp":
            runs.append(run_fmpy_ssp(system, ssp))
        else:
            osp = write_osp(system, files / ("osp" if ecco is None else "osp-ecco") / name)
            # ECCO runs through the API (ecco_execution); its OSP file is for the cosim CLI
            runs.append(run_libcosim(system, None if ecco is not None
                                     else osp if source == "osp" else ssp))
    for path in results.write_run(runs, scenario, out):
        print(path)
    return runs


def run(args: argparse.Namespace) -> int:
    scenario = scenarios.load(args.scenario)
    scenario.check_step(args.step)  # the bounds of cosim and sweep
    variants = cosim.selected_variants(scenario, args.variant)
    ecco = None if args.algorithm == "fixed" else EccoSettings(
        **{name: getattr(args, f"ecco_{name}") for name, _, _ in ECCO_OPTIONS})
    check_ecco(ecco, args.engine, args.source)  # before the output folder is made
    out = args.out or SYSTEM_DIR / scenario.name / (
        args.engine if ecco is None else f"{args.engine}-ecco")
    results.check_writable(out)  # before the runs, not after them
    run_system(scenario, variants, args.engine, args.step, out, args.source, ecco)
    print(results.summary_text(out / "summary.csv", scenario))
    return 0
