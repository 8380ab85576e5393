"""The harness's modules import each other without a cycle, and so do its rooms (its
packages): every import statement, at the top of a file or inside a function, read from the
source (a function-level import hides a cycle from a plain `import`, it does not remove it),
including those of any `if __name__ == "__main__":` block: a command is a module of its own,
run by `harness.cli`.

The rooms stand in layers (docs/code_structure.md), each importing only rooms below it:
the base modules (errors, io, interrupts, registry), then scenarios, fmu (building, loading
and calling FMUs), drive (motor, controller, metrics), engines, run (the cosim command,
result files, plots, compare), and the commands built on those (design, sweeps, study,
bench), the pages made from what they all write (report), then the command line."""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

import pytest

HARNESS = Path(__file__).resolve().parent.parent / "harness"


def module_name(path: Path) -> str:
    parts = path.relative_to(HARNESS.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(HARNESS.rglob("*.py"))}


def imported(name: str, path: Path) -> set[str]:
    """The harness modules the file imports: `import harness.a`, `from harness import a`
    (a module), `from harness.a import b` (harness.a, and harness.a.b if that is a module),
    relative imports resolved against the file's package."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(), str(path))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return {m for m in found if m in MODULES and m != "harness" and m != name}


GRAPH = {name: imported(name, path) for name, path in MODULES.items()}


# the rooms, lowest first; a room imports only rooms below it (or itself)
LAYERS = (("harness.errors", "harness.io", "harness.interrupts", "harness.registry"),
          ("harness.scenarios",), ("harness.fmu",), ("harness.drive",), ("harness.engines",),
          ("harness.run",), ("harness.design", "harness.sweeps"), ("harness.study",),
          ("harness.bench",), ("harness.report",),
          ("harness.cli", "harness.__main__"))
LAYER = {room: level for level, rooms in enumerate(LAYERS) for room in rooms}


def room(module: str) -> str:
    """The room of a module: its package below harness (or the module itself at the top)."""
    return ".".join(module.split(".")[:2])


ROOMS = {room(name) for name in MODULES if name != "harness"}


def test_the_graph_sees_the_imports_it_must() -> None:
    """The walk finds top-level, function-level and package imports (else a cycle could
    hide from the tests below)."""
    assert "harness.engines.result" in GRAPH["harness.run.results"]  # from ... import
    assert "harness.io" in GRAPH["harness.fmu.build"]               # from harness.io import
    assert "harness.fmu.build" in GRAPH["harness.engines.fmpy_master"]  # from harness.fmu import
    assert "harness.sweeps.definition" in GRAPH["harness.sweeps"]
    assert "harness.io" in GRAPH["harness.run.compare"]             # inside plot()
    assert "harness.scenarios" in GRAPH["harness.scenarios.losses"]  # a package
    assert GRAPH["harness.io"] == {"harness.errors"}           # its one-line errors
    assert GRAPH["harness.errors"] == set()


def test_harness_imports_are_acyclic() -> None:
    try:
        order = list(graphlib.TopologicalSorter(GRAPH).static_order())
    except graphlib.CycleError as error:
        # the cycle lists each module before one that imports it: reversed, each imports
        # the next
        pytest.fail(f"import cycle: {' -> '.join(reversed(error.args[1]))}")
    assert set(order) == set(MODULES)


def test_every_room_has_a_layer() -> None:
    assert ROOMS == set(LAYER)


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """The imports of graph that go from a room to a room above it."""
    return sorted(f"{name} -> {other}" for name, imports in graph.items() if name != "harness"
                  for other in imports if LAYER[room(other)] > LAYER[room(name)])


def test_no_room_imports_a_room_above_it() -> None:
    """Each import between rooms goes down the layers (or stays in one): no cycle between
    packages and no arrow from a lower room to a higher one."""
    assert not upward_imports(GRAPH)


def test_the_layer_check_sees_an_upward_import() -> None:
    """A drive module importing the engines, or the fmu room importing the run room, is an
    upward import; the scenarios importing the base is not."""
    graph = {"harness.drive.trace": {"harness.engines.result"},
             "harness.fmu.build": {"harness.run.results", "harness.scenarios"},
             "harness.scenarios": {"harness.registry"}}
    assert upward_imports(graph) == ["harness.drive.trace -> harness.engines.result",
                                     "harness.fmu.build -> harness.run.results"]
