"""The FMUs of fmu_src, found by their registrations (fmu_src.mechanism.Registration).

A slave script `fmu_src/<folders>/<Model>.py` (a capitalised name, the model identifier) that
declares `REGISTRATION = Registration(...)` at its top level is an FMU: `scripts` finds them
by reading them (no import), `registration` imports one to read its registration. Nothing
else in the harness lists the models, so adding a mechanism touches only its own folder
(docs/adding_a_mechanism.md).
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path
from typing import Any

from fmu_src.fmi.vocabulary import Causality
from fmu_src.mechanism import Registration

# the slave scripts' tree, read at each call (a test points it at a copy)
SOURCE_DIR = Path(__file__).resolve().parent.parent / "fmu_src"
REGISTRATION = "REGISTRATION"  # the name a slave script declares its registration under


def _declares_registration(path: Path) -> bool:
    """Whether the module at path assigns REGISTRATION at its top level (a line starting
    `REGISTRATION =`)."""
    return re.search(rf"^{REGISTRATION}\s*(:[^=\n]*)?=", path.read_text(), re.MULTILINE) is not None


def scripts(source_dir: Path | None = None) -> dict[str, Path]:
    """Model identifier -> slave script, for the scripts under source_dir (a capitalised file
    name, the model identifier, declaring a registration), in alphabetical order of model."""
    found = {path.stem: path for path in (source_dir or SOURCE_DIR).rglob("[A-Z]*.py")
             if _declares_registration(path)}
    return dict(sorted(found.items()))


def models(source_dir: Path | None = None) -> tuple[str, ...]:
    """The model identifiers of the slave scripts under source_dir, in alphabetical order."""
    return tuple(scripts(source_dir))


def module_name(model: str, source_dir: Path | None = None) -> str | None:
    """The dotted name of the model's slave script (fmu_src.<folders>.<model>); None if
    source_dir has no such script."""
    script = scripts(source_dir).get(model)
    if script is None:
        return None
    return ".".join(script.relative_to((source_dir or SOURCE_DIR).parent).with_suffix("").parts)


def registration(model: str, source_dir: Path | None = None) -> Registration | None:
    """The registration of the model's slave script under source_dir, imported from the
    import path (None if there is no such script, or it registers nothing)."""
    name = module_name(model, source_dir)
    if name is None:
        return None
    return getattr(importlib.import_module(name), REGISTRATION, None)


def _instance(model: str) -> Any:
    """An instance of the model's slave class outside an FMU (no resources)."""
    return getattr(importlib.import_module(module_name(model)), model)(
        instance_name=f"registry.{model}", resources=None)


def input_units(model: str) -> dict[str, str | None]:
    """The unit of each input of the model's slave (None for a Boolean), as its FMU declares
    it: read from an instance of the slave class."""
    slave = _instance(model)
    return {name: slave.info[name].unit for name in slave.variable_names(Causality.input)}


def mechanisms(source_dir: Path | None = None) -> dict[str, Registration]:
    """Model -> registration of every mechanism (a registration with a physics module)."""
    found = {model: registration(model, source_dir) for model in models(source_dir)}
    return {model: r for model, r in found.items() if r is not None and r.physics is not None}
