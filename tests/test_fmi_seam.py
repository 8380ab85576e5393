"""The FMI version seam: FMI 2.0 is named only inside the FMI layer, behind one interface.

The FMI layer is fmu_src/fmi and harness/fmu. What is FMI 2.0 lives in their fmi2 packages;
the rest of the layer is version-neutral and names FMI 2.0 only in its binding modules, which
choose the version (fmu_src.fmi.binding, harness.fmu.loader's VERSIONS, harness.fmu.build).
Every other module of fmu_src and harness speaks the layer's vocabulary
(fmu_src.fmi.vocabulary) and never imports an FMI 2.0 name, an fmi2 module or pythonfmu (FMI
2.0's exporter). Every import statement is read from the source, a function's included.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from fmu_src.fmi import binding
from harness.fmu import loader

ROOT = Path(__file__).resolve().parent.parent
MODULES = sorted([*(ROOT / "fmu_src").rglob("*.py"), *(ROOT / "harness").rglob("*.py")])
LAYER = (ROOT / "fmu_src" / "fmi", ROOT / "harness" / "fmu")
# the version-neutral modules of the layer that choose the FMI version
BINDINGS = {ROOT / "fmu_src" / "fmi" / "binding.py", ROOT / "harness" / "fmu" / "loader.py",
            ROOT / "harness" / "fmu" / "build.py"}


def fmi2_imports(source: str) -> list[str]:
    """What a source imports that is FMI 2.0's: a module with a part named fmi2... (fmpy.fmi2,
    fmu_src.fmi.fmi2.slave) or a name starting with Fmi2 or fmi2 (pythonfmu's Fmi2Slave,
    harness.fmu's fmi2 package)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names if _fmi2(alias.name)]
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if _fmi2(module):
                found.append(module)
            found += [f"{module}.{alias.name}" for alias in node.names
                      if alias.name.lower().startswith("fmi2")]
    return found


def _fmi2(module: str) -> bool:
    return any(part.lower().startswith("fmi2") for part in module.split("."))


def exporter_imports(source: str) -> list[str]:
    """The modules of pythonfmu, FMI 2.0's exporter, that a source imports."""
    found = []
    for node in ast.walk(ast.parse(source)):
        names = ([alias.name for alias in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level
                 else [])
        found += [name for name in names if name.split(".")[0] == "pythonfmu"]
    return found


def in_layer(path: Path) -> bool:
    return any(path.is_relative_to(folder) for folder in LAYER)


def fmi2_package(path: Path) -> bool:
    return in_layer(path) and "fmi2" in path.relative_to(ROOT).parts[:-1]


def test_the_checks_see_what_they_must() -> None:
    """Negative controls: each form of an FMI 2.0 import is found, at the top of a file or in
    a function, and the layer's vocabulary, FMPy and its FMI-neutral modules are not."""
    sources = {
        "from pythonfmu import Fmi2Causality, Real": ["pythonfmu.Fmi2Causality"],
        "from pythonfmu.enums import Fmi2Status as Status": ["pythonfmu.enums.Fmi2Status"],
        "import fmpy.fmi2": ["fmpy.fmi2"],
        "from fmpy.fmi2 import FMU2Slave": ["fmpy.fmi2"],
        "from harness.fmu import fmi2": ["harness.fmu.fmi2"],
        "def f():\n    from fmu_src.fmi.fmi2.slave import X\n": ["fmu_src.fmi.fmi2.slave"],
        "from fmu_src.fmi.vocabulary import Causality\nimport fmpy\n"
        "from fmpy.fmi1 import FMICallException": [],
    }
    for source, expected in sources.items():
        assert fmi2_imports(source) == expected, source
    assert exporter_imports("import pythonfmu.builder\nfrom pythonfmu import Real\n"
                            "from . import pythonfmu") == ["pythonfmu.builder", "pythonfmu"]
    assert len(MODULES) > 100 and any(fmi2_package(path) for path in MODULES)
    assert fmi2_imports((ROOT / "fmu_src" / "fmi" / "fmi2" / "slave.py").read_text())


@pytest.mark.parametrize("path", [p for p in MODULES if not in_layer(p)],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_module_outside_the_fmi_layer_names_fmi2(path: Path) -> None:
    source = path.read_text()
    assert fmi2_imports(source) == [], "use fmu_src.fmi.vocabulary or the harness.fmu facades"
    assert exporter_imports(source) == [], "pythonfmu is FMI 2.0's: use fmu_src.fmi"


@pytest.mark.parametrize("path", [p for p in MODULES if in_layer(p) and not fmi2_package(p)
                                  and p not in BINDINGS],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_the_neutral_modules_of_the_layer_name_fmi2_only_in_their_bindings(path: Path) -> None:
    assert fmi2_imports(path.read_text()) == [], "choose the version in a binding module"


def test_every_version_offers_the_interface_the_neutral_modules_use() -> None:
    """What an FMI version's sibling must provide: its slave adaptors (fmu_src.fmi.binding)
    and its FMPy plumbing (harness.fmu.loader.VERSIONS), by name."""
    for adaptor in (binding.Adaptor, binding.ModelAdaptor):
        for name in ("declare", "causality_of", "type_of", "report", "standard", "calls",
                     "get_integer", "set_integer", "get_boolean", "set_boolean", "get_string",
                     "set_string", "_fmu_state_to_bytes", "_fmu_state_from_bytes",
                     "_get_log_queue"):
            assert hasattr(adaptor, name), (adaptor, name)
    assert binding.ModelAdaptor.to_xml is not binding.Adaptor.to_xml
    for version, plumbing in loader.VERSIONS.items():
        assert plumbing.VERSION == version
        for name in ("REAL", "BOOLEAN", "STRING", "GETTERS", "SETTERS", "C_BOOLEAN", "C_FALSE",
                     "GET_REAL", "SET_REAL", "GET_BOOLEAN", "SET_BOOLEAN", "DO_STEP",
                     "callbacks", "co_simulation", "model_exchange", "initialize",
                     "update_discrete_states", "get_derivatives", "references", "array_call",
                     "step_call"):
            assert hasattr(plumbing, name), (version, name)
