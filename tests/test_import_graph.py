"""The harness's modules import each other without a cycle: every import statement, at the
top of a file or inside a function, read from the source (a function-level import hides a
cycle from a plain `import`, it does not remove it), including those of any
`if __name__ == "__main__":` block: a command is a module of its own, run by `harness.cli`."""

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


def test_the_graph_sees_the_imports_it_must() -> None:
    """The walk finds top-level, function-level and package imports (else a cycle could
    hide from the test below)."""
    assert "harness.run.master" in GRAPH["harness.run.results"]     # from harness.run.master import
    assert "harness.io" in GRAPH["harness.fmu.build"]               # from harness.io import
    assert "harness.fmu.build" in GRAPH["harness.run.master"]       # from harness.fmu import
    assert "harness.sweeps.definition" in GRAPH["harness.sweeps"]
    assert "harness.io" in GRAPH["harness.run.compare"]             # inside plot()
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
