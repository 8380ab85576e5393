"""Parameter fields with FMI metadata, and their range check (standard library only).

A physics module declares its parameters as a frozen dataclass whose fields come from
`parameter(...)`: the default, the unit and description written to the model description,
and the physical bounds that `check_ranges` enforces and the FMU declares as min/max.
"""

from __future__ import annotations

import math
from dataclasses import field, fields
from typing import Any

# No parameter or input of these models may exceed this magnitude, nor be non-zero and below
# its inverse (SI units): products and quotients of a few of them (k a b, J omega^2,
# k r / (g R)) must stay inside double precision, and no physical quantity of a bench-top
# mechanism comes near either bound.
MAGNITUDE_LIMIT = 1e50


class DomainError(ValueError):
    """The physics refuses a state or input it cannot integrate (a released slider with
    neither mass nor damping, a step beyond the sub-step bound): the FMU refuses the step
    with the status Discard and keeps its state. Any other exception of a step is a defect."""


def magnitude_problem(value: float) -> str | None:
    """Why a finite value is outside the magnitudes these models accept, or None."""
    if abs(value) > MAGNITUDE_LIMIT:
        return f"is beyond the magnitude limit {MAGNITUDE_LIMIT:g} of these models"
    if 0.0 < abs(value) < 1.0 / MAGNITUDE_LIMIT:
        return (f"is non-zero and below the smallest magnitude {1.0 / MAGNITUDE_LIMIT:g} of "
                "these models")
    return None


def parameter(default: float | bool, unit: str | None, description: str, *,
              min: float | None = None, max: float | None = None,
              min_exclusive: bool = False) -> Any:
    """Dataclass field carrying the FMI unit, description and physical bounds."""
    return field(default=default, metadata=dict(
        unit=unit, description=description, min=min, max=max, min_exclusive=min_exclusive))


def check_ranges(data: Any) -> None:
    """Raise ValueError naming the first numeric field that is NaN or outside its bounds.

    Messages start with the field name (the command line relies on it to name its option).
    Magnitudes beyond MAGNITUDE_LIMIT, or non-zero below its inverse, are refused too.
    """
    for f in fields(data):
        value = getattr(data, f.name)
        if isinstance(value, bool):
            continue
        lo, hi, open_lo = f.metadata["min"], f.metadata["max"], f.metadata["min_exclusive"]
        allowed = ("(-inf" if lo is None else f"{'(' if open_lo else '['}{lo}") + ", " + (
            "inf)" if hi is None else f"{hi}]")
        unit = f.metadata["unit"]
        if not math.isfinite(value):
            raise ValueError(f"{f.name} = {value} {unit} is not a finite number in {allowed}")
        if (lo is not None and (value <= lo if open_lo else value < lo)) or (
                hi is not None and value > hi):
            raise ValueError(f"{f.name} = {value} {unit} is outside {allowed}")
        problem = magnitude_problem(value)
        if problem:
            raise ValueError(f"{f.name} = {value} {unit} {problem} (allowed {allowed})")
