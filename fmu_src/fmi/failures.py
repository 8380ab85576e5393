"""The FMUs' error policy: which exceptions refuse a step, and their messages (standard
library only).

A refusal that ends the call is a ValueError whose message names the variable and its range;
the FMU's runtime (fmu_src/runtime on Linux) returns the status Error and logs
"<FMI function>: ValueError: <message>" (pythonfmu's win64 binary returns Fatal with the
same message). A refusal of the physics (`fmu_src.parameters.DomainError`) or a failed
computation refuses a step (Discard); any other exception of a step is a defect.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fmu_src.parameters import DomainError

# ValueError texts of the math module: a failed computation, not a message of ours.
MATH_ERRORS = ("math domain error", "math range error")


def refused_setter(name: str, causality: str, standard: str) -> Callable[[Any], None]:
    """Setter of a variable the standard (its name: "FMI 2.0") does not let a host set (an
    output): refuses."""
    def refuse(value: Any) -> None:
        raise ValueError(f"{name} = {value!r} refused: {name} is of causality {causality}, "
                         "and only inputs, and parameters before initialisation, can be set "
                         f"({standard})")
    return refuse


def domain_failure(error: BaseException) -> bool:
    """A refusal of the physics (DomainError) or a failed computation (ArithmeticError, the
    math module's ValueErrors), which refuse a step; anything else is a defect."""
    return isinstance(error, (ArithmeticError, DomainError)) or (
        isinstance(error, ValueError) and str(error) in MATH_ERRORS)


def arithmetic_problem(error: ArithmeticError | ValueError) -> str:
    """The message of a failed step: ours as it is, the math module's and Python's
    arithmetic errors translated into what happened."""
    text = str(error)
    if isinstance(error, ValueError) and text not in MATH_ERRORS:
        return text
    return (f"the model's arithmetic failed ({text}): the parameters, inputs or state are "
            "beyond what double precision can represent")
