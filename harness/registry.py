"""The FMUs of fmu_src, found by their registrations (fmu_src.mechanism.Registration).

A slave script `fmu_src/<Model>.py` that declares `REGISTRATION = Registration(...)` at its
top level is an FMU: `models` finds the scripts by reading them (no import), `registration`
imports one to read its registration. Nothing else in the harness lists the models, so adding
a mechanism touches only its own files (docs/adding_a_mechanism.md).
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

from pythonfmu import Fmi2Causality

from fmu_src.mechanism import Registration

SOURCE_DIR = Path(__file__).resolve().parent.parent / "fmu_src"
REGISTRATION = "REGISTRATION"  # the name a slave script declares its registration under


def _declares_registration(path: Path) -> bool:
    """Whether the module at path assigns REGISTRATION at its top level (a line starting
    `REGISTRATION =`)."""
    return re.search(rf"^{REGISTRATION}\s*(:[^=\n]*)?=", path.read_text(), re.MULTILINE) is not None


def models(source_dir: Path = SOURCE_DIR) -> tuple[str, ...]:
    """The model identifiers of the slave scripts in source_dir, in alphabetical order."""
    return tuple(path.stem for path in sorted(source_dir.glob("*.py"))
                 if _declares_registration(path))


def registration(model: str) -> Registration | None:
    """The registration of the slave script fmu_src/<model>.py on the import path (None if
    there is no such script, or it registers nothing)."""
    try:
        module = importlib.import_module(f"fmu_src.{model}")
    except ModuleNotFoundError as error:
        if error.name != f"fmu_src.{model}":
            raise
        return None
    return getattr(module, REGISTRATION, None)


def input_units(model: str) -> dict[str, str | None]:
    """The unit of each input of the model's slave (None for a Boolean), as its FMU declares
    it: read from an instance of the slave class."""
    slave = getattr(importlib.import_module(f"fmu_src.{model}"), model)(
        instance_name=f"units.{model}", resources=None)
    return {var.name: slave.info[var.name].unit for var in slave.vars.values()
            if var.causality == Fmi2Causality.input}


def mechanisms(source_dir: Path = SOURCE_DIR) -> dict[str, Registration]:
    """Model -> registration of every mechanism (a registration with a physics module)."""
    found = {model: registration(model) for model in models(source_dir)}
    return {model: r for model, r in found.items() if r is not None and r.physics is not None}
