"""The system written as SSP (SystemStructure.ssd in a .ssp archive) and as OSP
(OspSystemStructure.xml beside the FMUs' OSP model descriptions)."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from harness.engines.system import System, model_variables
from harness.fmu import osp
from harness.io import write_atomic

# OMSimulator matches SSD elements by their qualified names: keep these prefixes
NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
      "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
      "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"}
# OMSimulator's fixed-step master ("oms-ma") needs tolerances although it steps no solver
OMS_TOLERANCE = 1e-4
OSP_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"

def _bindings(system: System) -> dict[str, list[tuple[str, str, str]]]:
    """Per component, its parameters as (name, FMI type of the variable, literal)."""
    variables = model_variables(system)
    return {component: [(name, variables[component][name].type,
                         str(value).lower() if isinstance(value, bool) else str(value))
                        for name, value in values.items()]
            for component, values in system.parameters.items()}


def ssd_tree(system: System) -> ET.ElementTree:
    """SystemStructure.ssd: components with connectors (every output, every connected
    input) and inline parameter bindings, connections, the system's OpenModelica annotation
    (OMSimulator's fixed-step master, without which OMSimulator 3.0 aborts) and a
    DefaultExperiment over the task [s], where OMSimulator's import reads the stop time (its
    command line overrides it with --stopTime: docs/using_the_fmus.md), whose OSP annotation
    gives the fixed step (libcosim)."""
    for prefix, uri in NS.items():
        ET.register_namespace(prefix, uri)
    ssd, ssc, ssv, osp_, oms = (f"{{{NS[p]}}}" for p in ("ssd", "ssc", "ssv", "osp", "oms"))
    variables = model_variables(system)
    bindings = _bindings(system)
    root = ET.Element(f"{ssd}SystemStructureDescription", version="1.0", name=system.name)
    root_system = ET.SubElement(root, f"{ssd}System", name=system.name,
                                description=system.plan.variant.description or system.name)
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
