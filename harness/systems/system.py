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
drive energies by less than the tolerances of tests/test_system.py.

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
Value = float | bool | int


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

    @property
    def name(self) -> str:
        return f"{self.scenario.name}_{self.variant.name}"


def controller(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's controller: `controller` or `controller_<joint>`."""
    return CONTROLLER + master.suffix(scenario, joint)


def drive(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's drive: `drive` or `drive_<joint>`."""
    return DRIVE + master.suffix(scenario, joint)


def describe(scenario: scenarios.Scenario, variant: scenarios.Variant,
             step_size: float = master.DEFAULT_STEP,
             design: ControllerDesign = ControllerDesign()) -> System:
    """The system of FMUs for a variant, with the harness's parameters and start (the
    ScenarioSequencer built for the scenario if build/fmus' one plays another). A variant's
    own joints get their controllers and drives too (`Scenario.for_variant`)."""
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
    return System(scenario, variant, step_size, models, parameters, tuple(connections), fmus)


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
    harness.fmu.osp) as one VariableGroupConnection each."""
    ET.register_namespace("", OSP_NS)
    ns = f"{{{OSP_NS}}}"
    root = ET.Element(f"{ns}OspSystemStructure", version="0.1")
    ET.SubElement(root, f"{ns}StartTime").text = "0.0"
    ET.SubElement(root, f"{ns}BaseStepSize").text = str(system.step_size)
    ET.SubElement(root, f"{ns}Algorithm").text = "fixedStep"
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
    groups = osp.group_connections(system.models, system.connections) if by_group else []
    grouped = {c for *_, covered in groups for c in covered}
    for start, start_variable, end, end_variable in system.connections:
        if (start, start_variable, end, end_variable) not in grouped:
            connection = ET.SubElement(connections, f"{ns}VariableConnection")
            ET.SubElement(connection, f"{ns}Variable", simulator=start, name=start_variable)
            ET.SubElement(connection, f"{ns}Variable", simulator=end, name=end_variable)
    for a, group_a, b, group_b, _ in groups:
        connection = ET.SubElement(connections, f"{ns}VariableGroupConnection")
        ET.SubElement(connection, f"{ns}VariableGroup", simulator=a, name=group_a)
        ET.SubElement(connection, f"{ns}VariableGroup", simulator=b, name=group_b)
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
            messages: list[str]) -> master.RunResult:
    """A RunResult from every communication point's values (frame, row k at t_k, columns
    `component.variable`) and the Boolean values at the recording points."""
    scenario = system.scenario
    variables = _model_variables(system)
    record = _recorded(system, variables)
    every = max(1, round(master.RECORD_INTERVAL / system.step_size))
    mechanism_columns = [n for n in record[MECHANISM] if f"{MECHANISM}.{n}" in frame
                         or n in booleans]
    rows = frame.iloc[::every]
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
            joint, motor, system.step_size, voltage[:-1], current,
            frame[f"{power}.tau_drive"].to_numpy()[:-1],
            start_currents(motor, system.step_size, voltage[:-1], speed[:-1], current),
            frame[f"{MECHANISM}.{joint.position}"].to_numpy(), speed,
            frame[f"{SEQUENCER}.{joint.position}_ref"].to_numpy()))
        gains[joint.name] = PIDGains(*(float(system.parameters[control][n])
                                       for n in PIDGains._fields))
    return master.assemble(scenario, system.variant, system.models[MECHANISM], table, traces,
                           gains, dict(system.parameters[MECHANISM]), messages)


def _time_series(observer, slave: int, reference: int, steps: int) -> np.ndarray:
    """Samples of steps 0..steps from a libcosim time-series observer.

    libcosimpy 0.0.6 trims its answer by the number of zero step numbers, which drops one
    real sample when step 0 is among them: ask again from where the answer stopped.
    """
    values: list[float] = []
    while len(values) <= steps:
        _, numbers, samples = observer.time_series_real_samples(
            slave, reference, len(values), steps + 2 - len(values))
        if not numbers or numbers[0] != len(values):
            raise RuntimeError(f"libcosim time series of variable {reference} ends at step "
                               f"{len(values)} of {steps}")
        values.extend(samples)
    return np.asarray(values[:steps + 1])


def run_libcosim(system: System, source: Path) -> master.RunResult:
    """Run an OspSystemStructure.xml or an .ssp archive in libcosim (fixed step).

    Real variables come from a time-series observer at every step; Booleans, which it does
    not record, from a last-value observer at the recording points (at t = 0, which that
    observer cannot see, the scenario's inputs and the values after the first step).
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    nanoseconds = round(system.step_size * 1e9)
    if source.suffix == ".ssp":  # libcosim needs the step size given for an SSP
        execution = CosimExecution.from_ssp_file(str(source), step_size=nanoseconds)
    else:
        execution = CosimExecution.from_osp_config_file(str(source))
    steps = round(system.scenario.duration / system.step_size)
    every = max(1, round(master.RECORD_INTERVAL / system.step_size))
    series = CosimObserver.create_time_series(buffer_size=steps + 1)
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
                                                        steps)
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
                        "build/system/<scenario>/<engine>); SSP and OSP files go to "
                        "build/system/<scenario>/")


def run_system(scenario: scenarios.Scenario, variants: list[str], engine: str,
               step_size: float, out: Path, source: str = "osp") -> list[master.RunResult]:
    """Describe, write and run each variant's system; write results into out."""
    if engine not in ENGINES:
        raise UserError(f"engine {engine!r} is not one of {', '.join(ENGINES)}")
    runs = []
    for name in tqdm(variants, desc=f"{scenario.name} system ({engine})", unit="variant"):
        system = describe(scenario, scenario.variant(name), step_size)
        files = SYSTEM_DIR / scenario.name
        ssp = write_ssp(system, files / f"{name}.ssp")
        if engine == "fmpy-ssp":
            runs.append(run_fmpy_ssp(system, ssp))
        else:
            osp = write_osp(system, files / "osp" / name)
            runs.append(run_libcosim(system, osp if source == "osp" else ssp))
    for path in results.write_run(runs, scenario, out):
        print(path)
    return runs


def run(args: argparse.Namespace) -> int:
    scenario = scenarios.load(args.scenario)
    scenario.check_step(args.step)  # the bounds of cosim and sweep
    variants = cosim.selected_variants(scenario, args.variant)
    out = args.out or SYSTEM_DIR / scenario.name / args.engine
    results.check_writable(out)  # before the runs, not after them
    run_system(scenario, variants, args.engine, args.step, out, args.source)
    print(results.summary_text(out / "summary.csv", scenario))
    return 0
