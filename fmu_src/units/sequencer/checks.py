"""Checks of the values a parsed TOML file holds (standard library only): each returns the
value if it is what a key allows, else raises a ValueError naming the key (`what`, `where`)
and what it allows. The scenario format (`scenario_format`), the loss files
(`harness.scenarios.losses`) and the sweep files (`harness.sweeps.definition`) read their
keys with them."""

from __future__ import annotations

import math
import re
from typing import Any

from fmu_src.parameters import MAGNITUDE_LIMIT

# scenario and variant names become file and folder names: no path separators, no "..",
# not empty, not hidden
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_+-]*(\.[A-Za-z0-9_+-]+)*")


def shown(value: Any, width: int = 60) -> str:
    """repr(value) for a message, shortened to about width characters."""
    text = repr(value) if not isinstance(value, int) or value.bit_length() < 200 else (
        f"an integer of about {int(value.bit_length() * math.log10(2))} digits")
    return text if len(text) <= width else f"{text[:width - 5]} ...{text[-1]}"


def check_name(name: Any, what: str) -> str:
    """name if it is a usable file name (NAME_PATTERN), else ValueError naming `what`."""
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise ValueError(f"{what} = {shown(name)} must be letters, digits, '_', '-', '+' and inner "
                         "dots, starting with a letter or digit (it names result files)")
    return name


def table(value: Any, what: str) -> dict[str, Any]:
    """value if it is a table (dict), else ValueError naming `what`."""
    if not isinstance(value, dict):
        raise ValueError(f"{what} = {shown(value)} must be a table")
    return value


def table_list(value: Any, what: str) -> list[dict[str, Any]]:
    """value if it is a non-empty list of tables ([[what]]), else ValueError naming it."""
    if not isinstance(value, list) or not value or not all(isinstance(v, dict) for v in value):
        raise ValueError(f"{what} = {shown(value)} must be a list of [[{what}]] tables")
    return value


def unknown_keys(raw: dict[str, Any], allowed: tuple[str, ...], where: str) -> None:
    """ValueError naming the keys of raw that are not among allowed, if any."""
    unknown = sorted(set(raw) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}; "
                         f"allowed: {', '.join(allowed)}")


def finite_number(value: Any, what: str, allowed: str = "a finite number") -> float:
    """value as a float if it is a finite number (not a boolean; an integer beyond the range
    of a float is not), else ValueError naming it."""
    if not isinstance(value, bool) and isinstance(value, (int, float)):
        try:
            number = float(value)
        except OverflowError:  # a TOML integer beyond 1.8e308
            number = math.inf
        if math.isfinite(number):
            return number
    raise ValueError(f"{what} = {shown(value)} is not {allowed}")


def parameter_values(raw: Any, where: str) -> dict[str, float | bool]:
    """A table of name = finite number or boolean, the numbers as floats, else ValueError."""
    if not isinstance(raw, dict):
        raise ValueError(f"{where} = {shown(raw)} must be a table of name = number or boolean")
    return {k: v if isinstance(v, bool) else finite_number(v, f"{where} {k}", "a finite "
                                                           "number or boolean")
            for k, v in raw.items()}


def position(value: Any, what: str, unit: str = "rad or m") -> float:
    """A joint position [rad or m]: finite and of magnitude at most MAGNITUDE_LIMIT, else
    ValueError naming it."""
    number = finite_number(value, what, f"a finite number [{unit}]")
    if abs(number) > MAGNITUDE_LIMIT:
        raise ValueError(f"{what} = {shown(value)} {unit} is outside [-{MAGNITUDE_LIMIT:g}, "
                         f"{MAGNITUDE_LIMIT:g}]")
    return number
