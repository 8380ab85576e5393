"""OSP interface specification (OSP-IS 1.0.1) of the FMUs: `<Model>_OspModelDescription.xml`.

libcosim (and other OSP tools) read this file from beside an FMU. It declares the FMU's
variable groups, so that an OspSystemStructure.xml can connect two FMUs port to port with one
`VariableGroupConnection` instead of one `VariableConnection` per variable:

- `AngularMechanicalPort` (Torque, AngularVelocity): each revolute joint of a mechanism (the
  drive torque in, the joint speed out) and the drive's shaft (torque out, speed in);
- `LinearMechanicalPort` (Force, LinearVelocity): the prismatic joint of PrismaticCompensator;
- `ElectromagneticPort` (Voltage, Current): the drive's armature (voltage in, current out),
  and a `Voltage` group on the controller's output that feeds it.

The groups' units are the FMU's own (modelDescription.xml), repeated under UnitDefinitions
with their SI base units. The groups are the ports each FMU's registration declares
(fmu_src.mechanism.Registration.ports, read by `model_groups`); a DcMotorDrive set up as
a lead-screw drive still declares its shaft as angular (its variables are declared in N m and
rad/s), so it meets the prismatic joint variable by variable.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

from fmpy import read_model_description
from fmpy.model_description import ModelDescription

from fmu_src.mechanism import Port, Quantity
from harness import registry
from harness.io import write_atomic

NAMESPACE = "https://open-simulation-platform.com/OspModelDescription/1.0.1"
SUFFIX = "_OspModelDescription.xml"
# the variable group kinds of OSP-IS 1.0.1 that the FMUs use, in the order of the schema's
# sequence (VariableGroupsType), which the groups of a model must follow
SCHEMA_ORDER = ("Generic", "Force", "Torque", "Voltage", "Pressure", "LinearVelocity",
                "AngularVelocity", "Current", "VolumeFlowRate", "LinearMechanicalPort",
                "AngularMechanicalPort", "ElectromagneticPort", "HydraulicPort")
# port kind -> the kinds of its two single-quantity groups (effort, flow), as the schema orders
PORT_KINDS = {"AngularMechanicalPort": ("Torque", "AngularVelocity"),
              "LinearMechanicalPort": ("Force", "LinearVelocity"),
              "ElectromagneticPort": ("Voltage", "Current")}


@dataclass(frozen=True)
class Group:
    """A variable group: a single quantity (kind, variables) or a port of two such groups."""

    kind: str
    name: str
    variables: tuple[str, ...] = ()
    members: tuple[Group, ...] = ()


def port(kind: str, name: str, effort: str, flow: str) -> Group:
    """A power port: its effort and flow groups are named <name>_<quantity>, e.g.
    shaft_angular_velocity."""
    effort_kind, flow_kind = PORT_KINDS[kind]
    return Group(kind, name, members=tuple(
        Group(quantity, name + re.sub("([A-Z])", r"_\1", quantity).lower(), (variable,))
        for quantity, variable in ((effort_kind, effort), (flow_kind, flow))))


def model_groups(model: str) -> tuple[Group, ...]:
    """The variable groups of a model, from the ports of its registration (harness.registry;
    none for a model without one), in the order the schema's sequence puts their kinds."""
    found = registry.registration(model)
    declared = () if found is None else found.ports
    built = [Group(p.kind, p.name, p.variables) if isinstance(p, Quantity)
             else port(p.kind, p.name, p.effort, p.flow) for p in declared]
    unknown = [g.kind for g in built if g.kind not in SCHEMA_ORDER]
    if unknown:
        raise ValueError(f"{model}: OSP-IS has no variable group kind {', '.join(unknown)}")
    return tuple(sorted(built, key=lambda g: SCHEMA_ORDER.index(g.kind)))


def groups(model: str) -> list[Group]:
    """Every variable group of a model (none for a model without ports), ports before
    the groups they hold."""
    found: list[Group] = []
    pending = list(model_groups(model))
    while pending:
        group = pending.pop(0)
        found.append(group)
        pending.extend(group.members)
    return found


def _unit(md: ModelDescription, name: str) -> str:
    variable = next((v for v in md.modelVariables if v.name == name), None)
    if variable is None:
        raise ValueError(f"{md.modelName} has no variable {name!r} for its OSP variable group")
    unit = variable.unit or (variable.declaredType.unit if variable.declaredType else None)
    if unit is None:
        raise ValueError(f"{md.modelName}.{name} has no unit for its OSP variable group")
    return unit


def model_description_tree(md: ModelDescription) -> ET.ElementTree:
    """The OspModelDescription of an FMU from its modelDescription.xml."""
    ns = f"{{{NAMESPACE}}}"
    ET.register_namespace("", NAMESPACE)
    root = ET.Element(f"{ns}OspModelDescription", version="1.0")
    units = {name: _unit(md, name) for group in groups(md.modelName)
             for name in group.variables}
    definitions = ET.SubElement(root, f"{ns}UnitDefinitions")
    base_units = {u.name: u.baseUnit for u in md.unitDefinitions}
    for unit in sorted(set(units.values())):
        base = base_units[unit]
        ET.SubElement(ET.SubElement(definitions, f"{ns}Unit", name=unit), f"{ns}BaseUnit",
                      {k: str(getattr(base, k)) for k in
                       ("kg", "m", "s", "A", "K", "mol", "cd", "rad", "factor", "offset")})

    def add(parent: ET.Element, group: Group) -> None:
        element = ET.SubElement(parent, f"{ns}{group.kind}", name=group.name)
        for name in group.variables:
            ET.SubElement(element, f"{ns}Variable", ref=name, unit=units[name])
        for member in group.members:
            add(element, member)

    variable_groups = ET.SubElement(root, f"{ns}VariableGroups")  # libcosim needs it, even empty
    for group in model_groups(md.modelName):
        add(variable_groups, group)
    ET.indent(root)
    return ET.ElementTree(root)


def write_model_description(fmu: Path, folder: Path | None = None) -> Path:
    """Write <Model>_OspModelDescription.xml for the FMU into folder (default: beside the
    FMU), atomically, and return its path."""
    md = read_model_description(str(fmu))
    path = (folder or fmu.parent) / f"{md.modelName}{SUFFIX}"
    return write_atomic(path, lambda tmp: model_description_tree(md).write(
        tmp, encoding="utf-8", xml_declaration=True))


def group_connections(models: dict[str, str],
                      connections: tuple[tuple[str, str, str, str], ...]
                      ) -> list[tuple[str, str, str, str, list[tuple[str, str, str, str]]]]:
    """Variable groups that connections join whole: (component, group, component, group, the
    connections that group connection stands for). Two groups of the same kind are joined
    when each of their variables is connected to its counterpart (either direction); ports
    are matched first, and a connection belongs to one group connection at most."""
    wired = set(connections)
    taken: set[tuple[str, str, str, str]] = set()
    found = []
    for (a, model_a), (b, model_b) in itertools.combinations(models.items(), 2):
        for group_a, group_b in itertools.product(groups(model_a), groups(model_b)):
            if group_a.kind != group_b.kind:
                continue
            pairs = _pairs(a, group_a, b, group_b)
            covered = [c for p in pairs for c in (p, (p[2], p[3], p[0], p[1])) if c in wired]
            if len(covered) == len(pairs) and not taken & set(covered):
                taken.update(covered)
                found.append((a, group_a.name, b, group_b.name, covered))
    return found


def _pairs(a: str, group_a: Group, b: str, group_b: Group) -> list[tuple[str, str, str, str]]:
    """The variable pairs a connection of two groups of the same kind makes (libcosim pairs
    the variables in order, and a port's groups in order)."""
    pairs = [(a, x, b, y) for x, y in zip(group_a.variables, group_b.variables, strict=True)]
    for member_a, member_b in zip(group_a.members, group_b.members, strict=True):
        pairs.extend(_pairs(a, member_a, b, member_b))
    return pairs


@dataclass(frozen=True)
class PowerBond:
    """A power bond (ECCO, docs/results.md#power-bonds): the effort `source` puts out
    (source_effort, its output) is `sink`'s input (sink_effort), and the flow `sink` puts out
    (sink_flow) is `source`'s input (source_flow). Both sides are registered ports."""

    name: str
    source: str
    source_effort: str
    source_flow: str
    sink: str
    sink_effort: str
    sink_flow: str


def power_bonds(models: dict[str, str], connections: tuple[tuple[str, str, str, str], ...]
                ) -> list[PowerBond]:
    """The power bonds of a system: every pair of registered ports (fmu_src.mechanism.Port,
    harness.registry) of two components that the connections join effort to effort one way
    and flow to flow the other way, e.g. the drive's shaft and the mechanism's joint. A
    lead-screw drive's angular shaft meets a prismatic joint this way too."""
    wired = set(connections)
    ports = {component: [p for p in getattr(registry.registration(model), "ports", ())
                         if isinstance(p, Port)] for component, model in models.items()}
    return [PowerBond(f"{a}.{port_a.name}-{b}.{port_b.name}", a, port_a.effort, port_a.flow,
                      b, port_b.effort, port_b.flow)
            for (a, ports_a), (b, ports_b) in itertools.permutations(ports.items(), 2)
            for port_a, port_b in itertools.product(ports_a, ports_b)
            if (a, port_a.effort, b, port_b.effort) in wired
            and (b, port_b.flow, a, port_a.flow) in wired]
