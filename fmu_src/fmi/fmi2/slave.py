"""The FMI 2.0 adaptor of the slaves: pythonfmu's `Fmi2Slave` in the layer's vocabulary
(standard library and pythonfmu only).

`Fmi2Adaptor` declares variables, reports messages and answers what a declared variable is
(`fmu_src.fmi.binding` lists what every version's adaptor provides); `Fmi2ModelAdaptor` adds
what the layer's model slaves (`fmu_src.fmi.variables`) need of pythonfmu besides: its
resources folder taken off sys.path again, and the model description completed
(`fmu_src.fmi.fmi2.model_description`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable
from typing import Any
from xml.etree.ElementTree import Element

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import ScalarVariable

from fmu_src.fmi.fmi2 import model_description
from fmu_src.fmi.vocabulary import (
    CallNames,
    Causality,
    Initial,
    Status,
    ValueType,
    Variability,
)

# the vocabulary's words in pythonfmu's FMI 2.0 terms
VARIABLES = {ValueType.real: Real, ValueType.integer: Integer, ValueType.boolean: Boolean,
             ValueType.string: String}
CAUSALITIES = {causality: Fmi2Causality[causality.name] for causality in Causality}
VARIABILITIES = {variability: Fmi2Variability[variability.name] for variability in Variability}
INITIALS = {initial: Fmi2Initial[initial.name] for initial in Initial}
STATUSES = {status: Fmi2Status[status.name] for status in Status}
# and back
VALUE_TYPES = {variable: value_type for value_type, variable in VARIABLES.items()}
CAUSALITY_OF = {fmi2: causality for causality, fmi2 in CAUSALITIES.items()}


class Fmi2Adaptor(Fmi2Slave):
    """pythonfmu's Fmi2Slave in the layer's vocabulary: a slave's variables are pythonfmu's
    (in `vars`, by value reference), its messages go to pythonfmu's log queue."""

    standard = "FMI 2.0"
    calls = CallNames(do_step="fmi2DoStep", setup_experiment="fmi2SetupExperiment",
                      exit_initialization_mode="fmi2ExitInitializationMode")

    def declare(self, value_type: ValueType, name: str, causality: Causality,
                variability: Variability, description: str, initial: Initial | None = None,
                getter: Callable[[], Any] | None = None) -> ScalarVariable:
        """Register a variable (its value reference: its position in `vars`), read through
        getter or else the attribute of its name; the variable, whose getter and setter may
        be replaced."""
        var = VARIABLES[value_type](
            name, causality=CAUSALITIES[causality], variability=VARIABILITIES[variability],
            initial=None if initial is None else INITIALS[initial], description=description,
            getter=getter)
        self.register_variable(var)
        return var

    @staticmethod
    def causality_of(var: ScalarVariable) -> Causality:
        return CAUSALITY_OF[var.causality]

    @staticmethod
    def type_of(var: ScalarVariable) -> ValueType:
        return VALUE_TYPES[type(var)]

    def report(self, message: str, status: Status) -> None:
        """Log a message with the status (its category derived from it)."""
        self.log(message, STATUSES[status])


class Fmi2ModelAdaptor(Fmi2Adaptor):
    """The adaptor of the layer's model slaves: they declare every variable's metadata
    (`info`, dependencies, Model Exchange's states), which completes their model
    description."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        # pythonfmu's runtime puts the resources folder (where it reads slavemodule.txt)
        # first on sys.path at every instantiation, to import the slave module, and never
        # takes it out: one entry per instance, pointing at folders hosts delete. The module
        # is imported by now. (pythonfmu's builder removes its own entry itself.)
        if self.resources in sys.path and os.path.exists(
                os.path.join(self.resources, "slavemodule.txt")):
            with contextlib.suppress(ValueError):  # another thread's instance took it out
                sys.path.remove(self.resources)

    def to_xml(self, model_options: dict[str, str] = dict()) -> Element:  # noqa: B006
        return model_description.complete(super().to_xml(model_options), self)
