"""The FMI 2.0 model description of a slave (standard library only): pythonfmu's, completed.

PythonFMU 0.7.0 writes no units, no min/max, no TypeDefinitions and no InitialUnknowns.
`complete` adds them, in the way DNV's component-model does, from the slave's one
table of variable metadata (`VariableInfo`, also used to check inputs at run time) and the
units' table (`fmu_src.fmi.model_description`), and writes each output's `dependencies`, from
the inputs `add_output` declares it depends on.
"""

from __future__ import annotations

from typing import Any
from xml.etree.ElementTree import Element, SubElement

from fmu_src.fmi.model_description import (
    DISPLAY_UNITS,
    NEEDS_EXECUTION_TOOL,
    UNITS,
    unit_definitions,
)
from fmu_src.fmi.vocabulary import Causality

# FMI 2.0 ModelExchange attributes (besides modelIdentifier): the FMU needs
# fmi2CompletedIntegratorStep (a regime may change between events, see
# `me_completed_integrator_step` of fmu_src.fmi.model_exchange) and saves and restores its
# state as in co-simulation
MODEL_EXCHANGE_OPTIONS = {
    "needsExecutionTool": NEEDS_EXECUTION_TOOL,
    "completedIntegratorStepNotNeeded": "false",
    "canBeInstantiatedOnlyOncePerProcess": "false",
    "canNotUseMemoryManagementFunctions": "true",
    "canGetAndSetFMUstate": "true",
    "canSerializeFMUstate": "true",
    "providesDirectionalDerivative": "false",
}


def indices(indices: Any) -> str:
    """A ModelStructure dependencies attribute: variable indices in increasing order."""
    return " ".join(str(i) for i in sorted(indices))


def type_definitions(units: list[str]) -> Element:
    """The TypeDefinitions element: one Real SimpleType per unit, named after its quantity."""
    node = Element("TypeDefinitions")
    for unit in units:
        quantity = UNITS[unit][0]
        simple = SubElement(node, "SimpleType", attrib={"name": quantity})
        SubElement(simple, "Real", attrib={"quantity": quantity, "unit": unit})
    return node


def complete(root: Element, slave: Any) -> Element:
    """pythonfmu's model description root of the slave with what it leaves out: unit and
    type definitions, declared types, display units, min/max, each output's
    dependencies and the InitialUnknowns (from the slave's info and dependencies); for a
    slave with Model Exchange (`fmu_src.fmi.model_exchange`) its element, its continuous
    states' derivatives and its number of event indicators."""
    used_units = sorted({i.unit for i in slave.info.values() if i.unit is not None})
    cosimulation = root.find("CoSimulation")
    cosimulation.set("needsExecutionTool", NEEDS_EXECUTION_TOOL)
    position = list(root).index(cosimulation)
    derivative_of = getattr(slave, "derivative_of", None)
    if derivative_of is not None:
        root.set("numberOfEventIndicators", str(slave.me_indicator_count))
        root.insert(position, model_exchange(cosimulation))
        position += 1
    root.insert(position + 1, unit_definitions(used_units))
    root.insert(position + 2, type_definitions(used_units))

    initial_unknowns = []
    index_of: dict[str, int] = {}
    for index, element in enumerate(root.find("ModelVariables"), start=1):
        name = element.get("name")
        index_of[name] = index
        info = slave.info[name]
        real = element.find("Real")
        if real is not None:
            real.set("declaredType", UNITS[info.unit][0])
            if info.unit in DISPLAY_UNITS:
                real.set("displayUnit", DISPLAY_UNITS[info.unit][0])
            for key in ("min", "max"):
                if getattr(info, key) is not None:
                    real.set(key, f"{getattr(info, key):.16g}")
        if element.get("initial") == "calculated":
            initial_unknowns.append(index)
    structure = root.find("ModelStructure")
    names = list(index_of)
    states = [index_of[n] for n in getattr(slave, "state_variables", ())]
    for unknown in structure.iterfind("Outputs/Unknown"):
        name = names[int(unknown.get("index")) - 1]
        if name in getattr(slave, "state_variables", ()):   # a state: itself
            unknown.set("dependencies", str(index_of[name]))
            continue
        # the declared inputs and (a superset) the continuous states of Model Exchange
        unknown.set("dependencies", indices(
            {*states, *(index_of[n] for n in slave.dependencies[name])}))
    if derivative_of is not None:
        add_derivatives(root, structure, derivative_of, index_of)
    # At initialisation the knowns also include the parameters, which the initial state
    # is computed from: every parameter is listed (a superset), with the inputs declared.
    parameters = [index_of[name] for name in slave.variable_names(Causality.parameter)]
    if initial_unknowns:
        node = SubElement(structure, "InitialUnknowns")
        for index in initial_unknowns:
            inputs = slave.initial_dependencies.get(names[index - 1], ())
            dependencies = indices([*parameters, *(index_of[n] for n in inputs)])
            SubElement(node, "Unknown", attrib={"index": str(index),
                                                "dependencies": dependencies})
    return root


def model_exchange(cosimulation: Element) -> Element:
    """The ModelExchange element of an FMU whose CoSimulation element is cosimulation: the
    same model identifier (one binary serves both) and `MODEL_EXCHANGE_OPTIONS`."""
    return Element("ModelExchange", attrib={
        "modelIdentifier": cosimulation.get("modelIdentifier"), **MODEL_EXCHANGE_OPTIONS})


def add_derivatives(root: Element, structure: Element, derivative_of: dict[str, str],
                    index_of: dict[str, int]) -> None:
    """Each derivative variable's `derivative` attribute (its state's index) and the
    ModelStructure's Derivatives (after Outputs), each depending on every known (no
    dependencies attribute)."""
    variables = root.find("ModelVariables")
    node = Element("Derivatives")
    for name, state in derivative_of.items():
        index = index_of[name]
        variables[index - 1].find("Real").set("derivative", str(index_of[state]))
        SubElement(node, "Unknown", attrib={"index": str(index)})
    outputs = structure.find("Outputs")
    structure.insert(0 if outputs is None else list(structure).index(outputs) + 1, node)
