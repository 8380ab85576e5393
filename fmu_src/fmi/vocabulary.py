"""The FMI layer's own vocabulary (standard library only): what a slave declares about its
variables and what it reports, in the terms every FMI version shares.

The slaves, the sequencer and the harness speak it; the FMI version the slaves are bound to
(`fmu_src.fmi.binding`) maps it to its standard's enumerations. The names are the standards'
own spelling, so a causality reads the same here and in any version's model description.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum
from typing import NamedTuple


class Causality(Enum):
    """What a variable is to the host."""

    parameter = "parameter"
    calculatedParameter = "calculatedParameter"
    input = "input"
    output = "output"
    local = "local"


class Variability(Enum):
    """When a variable's value may change."""

    constant = "constant"
    fixed = "fixed"
    tunable = "tunable"
    discrete = "discrete"
    continuous = "continuous"


class Initial(Enum):
    """How a variable's start value is given."""

    exact = "exact"
    approx = "approx"
    calculated = "calculated"


class ValueType(Enum):
    """The type of a variable's value (its value: the type's name in messages)."""

    real = "Real"
    integer = "Integer"
    boolean = "Boolean"
    string = "String"


class Status(IntEnum):
    """The status of a message a slave logs, numbered as every FMI version numbers it."""

    ok = 0
    warning = 1
    discard = 2
    error = 3
    fatal = 4


class CallNames(NamedTuple):
    """The names of the standard's functions that a slave's messages name."""

    do_step: str
    setup_experiment: str  # the call that gives the start time
    exit_initialization_mode: str


@dataclass(frozen=True)
class DefaultExperiment:
    """The model description's DefaultExperiment of a slave [s] (None: not given)."""

    start_time: float | None = None
    stop_time: float | None = None
    step_size: float | None = None
    tolerance: float | None = None
