"""The units of the FMUs' variables (standard library only): the one table every model
description's unit definitions come from, in any FMI version.

PythonFMU 0.7.0 writes no units; each FMI version's writer (`fmu_src.fmi.fmi2.model_description`
for FMI 2.0) declares them from this table and the slave's metadata (`VariableInfo`), in the
way DNV's component-model does.
"""

from __future__ import annotations

import math
from xml.etree.ElementTree import Element, SubElement

# unit -> (quantity used as the declared type name, SI base-unit exponents)
UNITS: dict[str, tuple[str, dict[str, int]]] = {
    "1": ("Dimensionless", {}),
    "s": ("Time", {"s": 1}),
    "m": ("Length", {"m": 1}),
    "m/s": ("Velocity", {"m": 1, "s": -1}),
    "m/s2": ("Acceleration", {"m": 1, "s": -2}),
    "rad": ("Angle", {"rad": 1}),
    "rad/s": ("AngularVelocity", {"rad": 1, "s": -1}),
    "rad/s2": ("AngularAcceleration", {"rad": 1, "s": -2}),
    "kg": ("Mass", {"kg": 1}),
    "kg.m2": ("MomentOfInertia", {"kg": 1, "m": 2}),
    "N": ("Force", {"kg": 1, "m": 1, "s": -2}),
    "N.m": ("Torque", {"kg": 1, "m": 2, "s": -2}),
    "J": ("Energy", {"kg": 1, "m": 2, "s": -2}),
    "W": ("Power", {"kg": 1, "m": 2, "s": -3}),
    "N/m": ("TranslationalSpringConstant", {"kg": 1, "s": -2}),
    "N.s/m": ("TranslationalDampingConstant", {"kg": 1, "s": -1}),
    "N.m.s/rad": ("RotationalDampingConstant", {"kg": 1, "m": 2, "s": -1, "rad": -1}),
    "V": ("Voltage", {"kg": 1, "m": 2, "s": -3, "A": -1}),
    "A": ("Current", {"A": 1}),
    "Ohm": ("Resistance", {"kg": 1, "m": 2, "s": -3, "A": -2}),
    "H": ("Inductance", {"kg": 1, "m": 2, "s": -2, "A": -2}),
    "N.m/A": ("TorqueConstant", {"kg": 1, "m": 2, "s": -2, "A": -1}),
    "V/rad": ("VoltagePerAngle", {"kg": 1, "m": 2, "s": -3, "A": -1, "rad": -1}),
    "V/(rad.s)": ("VoltagePerAngleTime", {"kg": 1, "m": 2, "s": -4, "A": -1, "rad": -1}),
    "V.s/rad": ("VoltagePerAngularVelocity", {"kg": 1, "m": 2, "s": -2, "A": -1, "rad": -1}),
}
# display units: unit -> (display unit, factor): display = factor * value
DISPLAY_UNITS = {"rad": ("deg", 180.0 / math.pi), "rad/s": ("deg/s", 180.0 / math.pi)}



def unit_definitions(units: list[str]) -> Element:
    """The UnitDefinitions element of the units (names of UNITS): each unit's SI base-unit
    exponents and display unit."""
    node = Element("UnitDefinitions")
    for unit in units:
        unit_node = SubElement(node, "Unit", attrib={"name": unit})
        SubElement(unit_node, "BaseUnit", attrib={k: str(v) for k, v in UNITS[unit][1].items()})
        if unit in DISPLAY_UNITS:
            name, factor = DISPLAY_UNITS[unit]
            SubElement(unit_node, "DisplayUnit", attrib={"name": name, "factor": f"{factor:.16g}"})
    return node


# The FMUs contain their whole model: the Python code of the slave and of every module it
# imports, run by the FMU's own binary, which needs a CPython library as a C FMU needs the C
# runtime (docs/model_exchange.md); no tool has to execute them
NEEDS_EXECUTION_TOOL = "false"
