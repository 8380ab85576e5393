"""Build the FMUs of `fmu_src/` with pythonfmu.

Each FMU gets its slave script and exactly the `fmu_src` modules it imports (found by
reading the imports), staged as the package `fmu_src` in the FMU's resources, so the slave
runs in any Python interpreter with nothing but the standard library and pythonfmu's own
embedded files.

`fmu_src` is a namespace package (no __init__.py) on purpose: pythonfmu runs every FMU of a
process in one interpreter, each adding its resources folder to sys.path. A namespace
package's search path follows sys.path, so a second FMU finds its own modules even when an
earlier FMU imported `fmu_src` first (from a folder that may be deleted since).

Every FMU carries `documentation/index.html`, generated from the built FMU by
`harness.fmu_docs`. A build writes a temporary file in the destination folder and renames it
onto `<model>.fmu` only when the FMU and its documentation are complete, so an interrupted or
failed build never leaves a broken FMU behind (and a concurrent reader sees the old or the
new FMU, never a partial one).

Every FMU's linux64 binary is our loader (`harness/loader/fmi2_loader.c`, compiled here with
`python -m ziglang cc` for glibc 2.17 and later): it loads the libpython the FMU was built
with, recorded in `resources/python.txt`, when the host is not a Python process, then forwards
every FMI call to pythonfmu's binary, installed beside it as `<model>.pythonfmu.so`.

The ScenarioSequencer plays the scenario embedded in its module `sequencer_scenario`: the
committed `fmu_src/sequencer_scenario.py` (franchetti2021), or, with `--sequencer-scenario
FILE` (`build(..., sequencer_scenario=FILE)`), a module generated from that file into the
build's staging folder only, so the source tree keeps its default.
"""

from __future__ import annotations

import argparse
import ast
import platform
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from pathlib import Path

import fmpy
from pythonfmu.builder import FmuBuilder

from harness import fmu_docs, osp, scenarios
from harness.errors import UserError
from harness.io import write_atomic

SOURCE_DIR = Path(__file__).resolve().parent.parent / "fmu_src"
DEFAULT_DEST = SOURCE_DIR.parent / "build" / "fmus"
# Slave scripts, one per FMU: the file name is the model identifier.
MODELS = ("SelfRegulatingBalancer", "CiupituBalancer", "PrismaticCompensator", "DcMotorDrive",
          "PositionController", "ScenarioSequencer", "ActiveSpringBalancer",
          "RockingCounterweightBalancer")
SEQUENCER = "ScenarioSequencer"
LOADER_SOURCE = Path(__file__).resolve().parent / "loader" / "fmi2_loader.c"
LOADER_BUILD = DEFAULT_DEST.parent / "loader" / "fmi2_loader.so"
# the oldest glibc the loader runs on (pythonfmu's own binary needs 2.32)
LOADER_TARGET = "x86_64-linux-gnu.2.17"
PYTHON_RECORD = "resources/python.txt"  # read by the loader: keep the keys in step


def _fmu_src_imports(path: Path) -> set[str]:
    """Modules of the fmu_src package imported by the file at path."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module == "fmu_src":
                names.update(alias.name for alias in node.names)
            elif node.module.startswith("fmu_src."):
                names.add(node.module.split(".", 1)[1])
    return names


def dependencies(model: str, source_dir: Path = SOURCE_DIR) -> list[Path]:
    """fmu_src modules the slave script source_dir/<model>.py needs, followed transitively."""
    pending, found = [source_dir / f"{model}.py"], set()
    while pending:
        for name in _fmu_src_imports(pending.pop()):
            if name not in found:
                found.add(name)
                pending.append(SOURCE_DIR / f"{name}.py")
    return sorted(SOURCE_DIR / f"{name}.py" for name in found)


def sequencer_module(scenario: str | Path) -> str:
    """The source of the ScenarioSequencer's module `sequencer_scenario` for a scenario (name
    or file); ValueError if the file does not load or the sequencer cannot play it (a Real
    input without a unit in its INPUT_UNITS)."""
    from fmu_src.ScenarioSequencer import input_units  # pythonfmu: only for this model

    source = scenarios.embedded_source(scenario)  # loads the file: ValueError on a problem
    try:
        input_units(scenarios.load(scenario))
    except ValueError as error:
        raise UserError(f"{scenarios.scenario_file(scenario).name}: {error}") from None
    return source


def zig_cc(source: Path, output: Path, *options: str) -> Path:
    """Compile a C file with `python -m ziglang cc` (a registry package, no system compiler)
    for LOADER_TARGET, FMPy's FMI 2.0 headers on the include path; written atomically."""
    return write_atomic(output, lambda partial: subprocess.run(
        [sys.executable, "-m", "ziglang", "cc", "-target", LOADER_TARGET, "-O2", "-Wall",
         f"-I{Path(fmpy.__file__).parent / 'c-code'}", *options, str(source), "-o",
         str(partial)], check=True), mode=0o755)


def stale(output: Path, *sources: Path) -> bool:
    """True if output is missing or older than any of its sources."""
    return not output.exists() or output.stat().st_mtime < max(s.stat().st_mtime
                                                               for s in sources)


def loader_binary(output: Path = LOADER_BUILD) -> Path:
    """The compiled loader, rebuilt when its source is newer."""
    if not stale(output, LOADER_SOURCE):
        return output
    return zig_cc(LOADER_SOURCE, output, "-shared", "-fPIC", "-s")


def python_record() -> str:
    """resources/python.txt: the libpython of the interpreter building the FMU (empty when it
    is not a shared-library build), its version and its installation prefix."""
    shared = sysconfig.get_config_var("Py_ENABLE_SHARED")
    library = (Path(sysconfig.get_config_var("LIBDIR")) / sysconfig.get_config_var("INSTSONAME")
               if shared else "")
    return (f"libpython={library}\nversion={platform.python_version()}\n"
            f"prefix={sys.base_prefix}\n")


def install_loader(fmu: Path, model: str) -> None:
    """Make the loader the FMU's linux64 binary, pythonfmu's binary <model>.pythonfmu.so
    beside it, and record the building interpreter's libpython in resources/python.txt."""
    binary = f"binaries/linux64/{model}.so"
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
    with zipfile.ZipFile(fmu, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for info, data in entries:
            if info.filename == binary:
                info.filename = f"binaries/linux64/{model}.pythonfmu.so"
            archive.writestr(info, data)
        archive.write(loader_binary(), binary)
        archive.writestr(PYTHON_RECORD, python_record())


def build(model: str, dest: Path = DEFAULT_DEST, source_dir: Path = SOURCE_DIR,
          sequencer_scenario: str | Path | None = None) -> Path:
    """Build the slave script source_dir/<model>.py, with its documentation, into
    dest/<model>.fmu (atomically) and return that path.

    sequencer_scenario (ScenarioSequencer only): the scenario (shipped name or TOML file) the
    FMU plays instead of the committed default.
    """
    if sequencer_scenario is not None and model != SEQUENCER:
        raise UserError(f"a sequencer scenario is for the {SEQUENCER}, not {model}")
    embedded = None if sequencer_scenario is None else sequencer_module(sequencer_scenario)
    dest.mkdir(parents=True, exist_ok=True)
    script = source_dir / f"{model}.py"
    modules = dependencies(model, source_dir)
    fmu = dest / f"{model}.fmu"

    def write_fmu(partial: Path) -> None:
        with tempfile.TemporaryDirectory(prefix=f"build_{model}_") as tmp:
            stage = Path(tmp)
            package = stage / "fmu_src"
            package.mkdir()
            for module in modules:
                shutil.copy2(module, package)
            if embedded is not None:
                (package / "sequencer_scenario.py").write_text(embedded)
            FmuBuilder.build_FMU(
                shutil.copy2(script, stage), dest=partial,
                project_files=[package] if modules else [],
                canGetAndSetFMUstate=True, canSerializeFMUstate=True,
                canHandleVariableCommunicationStepSize=True)
            install_loader(partial, model)
            # the documentation reads the staged modules: those the FMU carries
            fmu_docs.add_documentation(partial, script,
                                       [package / module.name for module in modules])
    # pythonfmu takes a destination ending in .fmu as the file to write
    write_atomic(fmu, write_fmu, suffix=".fmu")
    osp.write_model_description(fmu)  # <Model>_OspModelDescription.xml beside it, for OSP
    return fmu


def build_all(dest: Path = DEFAULT_DEST) -> list[Path]:
    """Build every FMU of MODELS into dest."""
    return [build(model, dest) for model in MODELS]


def fmu_path(model: str, dest: Path = DEFAULT_DEST, source_dir: Path = SOURCE_DIR) -> Path:
    """Path of a built FMU; builds it if it is missing or older than its sources (the slave
    script, the fmu_src modules it uses and the documentation generator)."""
    fmu = dest / f"{model}.fmu"
    sources = [source_dir / f"{model}.py", *dependencies(model, source_dir),
               Path(fmu_docs.__file__), LOADER_SOURCE]
    if stale(fmu, *sources):
        build(model, dest, source_dir=source_dir)
    return fmu


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", dest="dest", type=Path, default=DEFAULT_DEST, metavar="DIR",
                        help="output folder")
    parser.add_argument("--dest", dest="dest", type=Path, default=argparse.SUPPRESS,
                        help=argparse.SUPPRESS)  # former spelling
    parser.add_argument(
        "--sequencer-scenario", metavar="NAME_OR_FILE",
        help=f"build only the {SEQUENCER}, playing this scenario (a name of "
             f"harness/scenarios or a TOML file) instead of franchetti2021, into "
             f"DIR/{SEQUENCER}.fmu (default: build every FMU)")


def run(args: argparse.Namespace) -> int:
    if args.sequencer_scenario is not None:
        print(build(SEQUENCER, args.dest, sequencer_scenario=args.sequencer_scenario))
        return 0
    for fmu in build_all(args.dest):
        print(fmu)
    return 0
