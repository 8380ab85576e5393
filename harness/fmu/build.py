"""Build the FMUs of `fmu_src/` with pythonfmu (its FMI 2.0 exporter, `harness.fmu.fmi2.build`).

Each FMU gets its slave script and exactly the `fmu_src` modules it imports (found by
reading the imports), staged as the package `fmu_src` in the FMU's resources, so the slave
runs in any Python interpreter with nothing but the standard library and pythonfmu's own
embedded files.

In a process, every FMU of our runtime imports the modules of its own bundle: the runtime
imports them as a package named after the digest of the bundle's Python files, with an
import hook bound to its resources folder (fmu_src/runtime/runtime_core.c, HELPER_SOURCE;
docs/build.md says why). `fmu_src` stays a namespace package (no __init__.py): under
pythonfmu's own binary (win64), which puts each FMU's resources folder on sys.path, its
search path follows sys.path.

Every FMU carries `documentation/index.html`, generated from the built FMU by
`harness.fmu.docs`. A build writes a temporary file in the destination folder and renames it
onto `<model>.fmu` only when the FMU and its documentation are complete, so an interrupted or
failed build never leaves a broken FMU behind (and a concurrent reader sees the old or the
new FMU, never a partial one).

Every FMU's linux64 binary is our FMI 2.0 runtime (`fmu_src/runtime/fmi2_functions.c` on the
version-neutral `runtime_core.c`, C only, compiled here with `python -m ziglang cc` for glibc
2.17 and later): it implements every FMI function over pythonfmu's Python API, loading the
libpython the FMU was built with (recorded in `resources/python.txt`, with the FMU's GUID)
when the host is not a Python process.
pythonfmu's own linux64 binary is not shipped; its win64 binary is. `build(..., runtime=False)`
keeps pythonfmu's binaries as they are: the benchmark's stock floor.

The ScenarioSequencer plays the scenario embedded in its module `sequencer_scenario`,
generated (`embedded_module`) into the build's staging folder only: from DEFAULT_SCENARIO, or,
with `--sequencer-scenario FILE` (`build(..., sequencer_scenario=FILE)`), from that file.

A build is by content: every FMU records in `resources/build_inputs.sha256` the digest of
everything that goes into it (`fmu_inputs`: the slave script and the fmu_src modules it
imports, the embedded scenario, the runtime's source and compiler, the building interpreter's
record, the versions of the tools that write it and this build code), and `fmu_path` or
`build-fmus` rebuild it only when that digest changes; the runtime and the bench's C host
record theirs beside the binary (`compiled`). Timestamps play no part, so a fresh clone, a
`touch` or a copy neither hides a change nor forces a rebuild, and an unchanged FMU keeps its
bytes and GUID. `build-fmus --force` rebuilds regardless.

A build is reproducible: the GUID is derived from that digest (`content_guid`), the model
description carries no generation time, and the archive's entries are sorted, dated
1980-01-01 and of mode 0644, so the same inputs give the same FMU to the byte.
"""

from __future__ import annotations

import argparse
import ast
import functools
import hashlib
import importlib.metadata
import platform
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import fmpy

from fmu_src.units.sequencer.ScenarioSequencer import EMBEDDED_MODULE
from harness import registry, scenarios
from harness.errors import UserError
from harness.fmu import docs as fmu_docs
from harness.fmu import osp
from harness.fmu.fmi2 import build as fmi2_build
from harness.io import write_atomic

SOURCE_DIR = registry.SOURCE_DIR
DEFAULT_DEST = SOURCE_DIR.parent / "build" / "fmus"
# Slave scripts, one per FMU: the file name is the model identifier.
MODELS = registry.models(SOURCE_DIR)  # those that declare a registration (harness.registry)
SEQUENCER = "ScenarioSequencer"
DEFAULT_SCENARIO = "franchetti2021"  # the scenario the sequencer of `make fmu` plays
# where the sequencer FMU's scenario module goes in the staged package fmu_src
EMBEDDED_SCENARIO = Path(*EMBEDDED_MODULE[1:])
# the runtime: its FMI 2.0 entry points, compiled with its version-neutral core and the FMI
# 2.0 state machine (their headers beside them, see compile_inputs)
RUNTIME_SOURCE = fmi2_build.RUNTIME_SOURCE
RUNTIME_CORE_SOURCE = SOURCE_DIR / "runtime" / "runtime_core.c"
STATE_MACHINE_SOURCE = fmi2_build.STATE_MACHINE_SOURCE
# the minimal C FMI host that runs an FMU outside any Python process (bench, tests)
HOST_SOURCE = fmi2_build.HOST_SOURCE
RUNTIME_BUILD = DEFAULT_DEST.parent / "runtime" / "fmi2_runtime.so"
# the oldest glibc the runtime runs on (pythonfmu's own binary needs 2.32)
RUNTIME_TARGET = "x86_64-linux-gnu.2.17"
RUNTIME_OPTIONS = ("-shared", "-fPIC", "-s", RUNTIME_CORE_SOURCE, STATE_MACHINE_SOURCE)
PYTHON_RECORD = "resources/python.txt"  # read by the runtime: keep the keys in step
INPUTS_RECORD = "resources/build_inputs.sha256"  # fmu_inputs of the FMU's build
# the code that writes an FMU besides its fmu_src modules, and the tools whose output it holds
BUILD_CODE = (Path(__file__), Path(fmi2_build.__file__), Path(fmu_docs.__file__),
              Path(osp.__file__), Path(registry.__file__))
TOOLS = ("pythonfmu", "fmpy", "ziglang", "matplotlib")


def _fmu_src_imports(path: Path) -> frozenset[str]:
    """Candidate fmu_src modules imported by the file at path (see `_imports_in`)."""
    return _imports_in(path.read_text())


@functools.cache  # parsed once per content: fmu_inputs reads them at every call
def _imports_in(source: str) -> frozenset[str]:
    """Dotted names below fmu_src that a Python source imports, each a module or a name in
    one: `from fmu_src.a import b` gives "a" and "a.b" (b a module or a name in a)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module:
            package = node.module.split(".", 1)
            if package[0] != "fmu_src":
                continue
            prefix = f"{package[1]}." if len(package) == 2 else ""
            if prefix:
                names.add(package[1])
            names.update(f"{prefix}{alias.name}" for alias in node.names)
    return frozenset(names)


def script(model: str, source_dir: Path = SOURCE_DIR) -> Path:
    """The slave script of the model under source_dir: a registered one, or (a slave that
    registers nothing, as the bench's floor) source_dir/<model>.py; UserError naming the
    models if there is none."""
    found = registry.scripts(source_dir)
    if model in found:
        return found[model]
    if (source_dir / f"{model}.py").is_file():
        return source_dir / f"{model}.py"
    raise UserError(f"unknown model {model!r}; choose from {', '.join(found)}")


def package_root(source_dir: Path) -> Path:
    """The fmu_src tree whose modules the slave scripts under source_dir import: SOURCE_DIR
    for a folder of it (the bench's floor), else source_dir itself (a copy of fmu_src, or a
    folder of slaves that import none of it)."""
    return SOURCE_DIR if source_dir.is_relative_to(SOURCE_DIR) else source_dir


def dependencies(model: str, source_dir: Path = SOURCE_DIR) -> list[Path]:
    """fmu_src modules the model's slave script needs, followed transitively (the
    sequencer's scenario module, generated at build time by `embedded_module`, is not among
    them)."""
    pending, found, root = [script(model, source_dir)], set(), package_root(source_dir)
    while pending:
        for name in _fmu_src_imports(pending.pop()):
            path = root.joinpath(*name.split(".")).with_suffix(".py")
            if path not in found and path.is_file():
                found.add(path)
                pending.append(path)
    return sorted(found)


def embedded_module(model: str, sequencer_scenario: str | Path | None = None) -> str | None:
    """The source of the module `sequencer_scenario` the FMU of the model carries: for the
    ScenarioSequencer, that of sequencer_scenario (name or file; None: DEFAULT_SCENARIO), and
    None for any other model. UserError if a scenario is given for another model, if its file
    does not load or if the sequencer cannot play it (a Real input that no mechanism of its
    variants has)."""
    if model != SEQUENCER:
        if sequencer_scenario is not None:
            raise UserError(f"a sequencer scenario is for the {SEQUENCER}, not {model}")
        return None
    scenario = DEFAULT_SCENARIO if sequencer_scenario is None else sequencer_scenario
    try:
        return scenarios.embedded_source(scenario)
    except UserError as error:
        raise UserError(f"{scenarios.scenario_file(scenario).name}: {error}") from None


def zig_cc(source: Path, output: Path, *options: str | Path) -> Path:
    """Compile a C file with `python -m ziglang cc` (a registry package, no system compiler)
    for RUNTIME_TARGET, FMPy's FMI headers on the include path; written atomically."""
    return write_atomic(output, lambda partial: subprocess.run(
        [sys.executable, "-m", "ziglang", "cc", "-target", RUNTIME_TARGET, "-O2", "-Wall",
         f"-I{Path(fmpy.__file__).parent / 'c-code'}", *options, str(source), "-o",
         str(partial)], check=True), mode=0o755)


def digest(*parts: Path | str) -> str:
    """SHA-256 (hex) of parts in order: a file by its name and bytes, a string as it is. Each
    part is length-prefixed, so different lists of parts never give the same stream."""
    sha = hashlib.sha256()
    for part in parts:
        data = (part.name.encode() + b"\0" + part.read_bytes() if isinstance(part, Path)
                else part.encode())
        sha.update(len(data).to_bytes(8, "big") + data)
    return sha.hexdigest()


@functools.cache
def tool_versions() -> str:
    """The installed versions of TOOLS, as `name=version` lines."""
    return "".join(f"{name}={importlib.metadata.version(name)}\n" for name in TOOLS)


def recorded_inputs(output: Path) -> str | None:
    """The digest of the inputs output was made from, as recorded: inside an FMU
    (INPUTS_RECORD), beside any other file (<output>.sha256); None if there is none."""
    try:
        if output.suffix == ".fmu":
            with zipfile.ZipFile(output) as archive:
                return archive.read(INPUTS_RECORD).decode()
        return output.with_name(f"{output.name}.sha256").read_text()
    except (OSError, KeyError, zipfile.BadZipFile):
        return None


def stale(output: Path, inputs: str) -> bool:
    """True unless output exists and records `inputs`, the digest of what it is made from."""
    return not output.exists() or recorded_inputs(output) != inputs


def compile_inputs(source: Path, *options: str | Path) -> str:
    """Digest of what `zig_cc(source, output, *options)` depends on: the source and the
    headers beside it, the options (a file among them, such as a second source, by its
    content), the target, the tools (ziglang, FMPy's headers) and this module (zig_cc's own
    flags)."""
    return digest(source, *sorted(source.parent.glob("*.h")), RUNTIME_TARGET, *options,
                  tool_versions(), Path(__file__))


def compiled(source: Path, output: Path, *options: str | Path) -> Path:
    """output compiled from source by zig_cc, unless the digest recorded beside it
    (<output>.sha256) says it was compiled from the same inputs (compile_inputs)."""
    inputs = compile_inputs(source, *options)
    if stale(output, inputs):
        record = output.with_name(f"{output.name}.sha256")
        record.unlink(missing_ok=True)  # no record vouches for output while it changes
        zig_cc(source, output, *options)
        record.write_text(inputs)       # a torn record never matches: no rename needed
    return output


def runtime_binary(output: Path = RUNTIME_BUILD) -> Path:
    """The compiled runtime, recompiled when its inputs change."""
    return compiled(RUNTIME_SOURCE, output, *RUNTIME_OPTIONS)


def libpython() -> Path | None:
    """The libpython of this interpreter; None when it is not a shared-library build."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        return None
    return Path(sysconfig.get_config_var("LIBDIR")) / sysconfig.get_config_var("INSTSONAME")


def python_record() -> str:
    """resources/python.txt: the libpython of the interpreter building the FMU (empty when it
    is not a shared-library build), its version and its installation prefix."""
    return (f"libpython={libpython() or ''}\nversion={platform.python_version()}\n"
            f"prefix={sys.base_prefix}\n")


MODEL_DESCRIPTION = "modelDescription.xml"
# every entry of a built FMU: one date (the earliest a zip can hold) and one mode
ENTRY_DATE = (1980, 1, 1, 0, 0, 0)
ENTRY_MODE = 0o100644


def content_guid(inputs: str) -> str:
    """The GUID of an FMU built from the inputs of digest `inputs`: the same inputs, the same
    GUID (a name-based UUID of the digest)."""
    return str(uuid.uuid5(uuid.NAMESPACE_URL, f"urn:gravity-balancer-fmu:{inputs}"))


def model_guid(fmu: Path) -> str:
    """The GUID in the FMU's modelDescription.xml."""
    with zipfile.ZipFile(fmu) as archive:
        return ElementTree.fromstring(archive.read(MODEL_DESCRIPTION)).get(
            fmi2_build.GUID_ATTRIBUTE)


def reproducible_description(text: str, guid: str) -> str:
    """pythonfmu's model description with the content GUID and without the generation time
    (an optional attribute), as it is otherwise."""
    attribute = fmi2_build.GUID_ATTRIBUTE
    text, guids = re.subn(rf'\b{attribute}="[^"]*"', f'{attribute}="{guid}"', text, count=1)
    if guids != 1:
        raise ValueError("the model description has no guid attribute")
    return re.sub(r'\s+generationDateAndTime="[^"]*"', "", text, count=1)


def write_archive(fmu: Path, entries: dict[str, bytes]) -> None:
    """The FMU's archive with these entries, sorted, each dated ENTRY_DATE with ENTRY_MODE."""
    with zipfile.ZipFile(fmu, "w") as archive:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, ENTRY_DATE)
            info.external_attr = ENTRY_MODE << 16
            info.create_system = 3  # Unix: the mode bits count
            archive.writestr(info, entries[name], compress_type=zipfile.ZIP_DEFLATED)


def archive_entries(fmu: Path) -> dict[str, bytes]:
    """The files of an FMU's archive by name."""
    with zipfile.ZipFile(fmu) as archive:
        return {info.filename: archive.read(info) for info in archive.infolist()
                if not info.is_dir()}


def install_runtime(fmu: Path, model: str, inputs: str, runtime: bool = True) -> None:
    """Make the runtime the FMU's linux64 binary in place of pythonfmu's (unless runtime is
    False), give the model description the content GUID, record the building interpreter's
    libpython and that GUID in resources/python.txt and the digest of the build's inputs in
    INPUTS_RECORD."""
    guid = content_guid(inputs)
    entries = archive_entries(fmu)
    entries[MODEL_DESCRIPTION] = reproducible_description(
        entries[MODEL_DESCRIPTION].decode(), guid).encode()
    if runtime:
        entries[fmi2_build.BINARY.format(model=model)] = runtime_binary().read_bytes()
    entries[PYTHON_RECORD] = f"{python_record()}guid={guid}\n".encode()
    entries[INPUTS_RECORD] = inputs.encode()
    write_archive(fmu, entries)


def fmu_inputs(model: str, source_dir: Path = SOURCE_DIR,
               sequencer_scenario: str | Path | None = None, runtime: bool = True) -> str:
    """Digest of everything that goes into the FMU of source_dir/<model>.py: the script, the
    fmu_src modules it imports, the embedded `sequencer_scenario` source (`embedded_module`),
    the runtime's inputs (or that pythonfmu's binary stays), the building interpreter's
    record, the tools' versions and BUILD_CODE."""
    return _inputs_digest(model, source_dir, embedded_module(model, sequencer_scenario),
                          runtime)


def _inputs_digest(model: str, source_dir: Path, embedded: str | None, runtime: bool) -> str:
    """`fmu_inputs` for the source of the embedded module (`embedded_module`), made once."""
    binary = (compile_inputs(RUNTIME_SOURCE, *RUNTIME_OPTIONS) if runtime
              else "pythonfmu's binaries")
    return digest(script(model, source_dir), *dependencies(model, source_dir),
                  "" if embedded is None else embedded, binary, python_record(),
                  tool_versions(), *BUILD_CODE)


def build(model: str, dest: Path = DEFAULT_DEST, source_dir: Path = SOURCE_DIR,
          sequencer_scenario: str | Path | None = None, runtime: bool = True) -> Path:
    """Build the slave script source_dir/<model>.py, with its documentation, into
    dest/<model>.fmu (atomically) and return that path, whether or not it is stale.

    sequencer_scenario (ScenarioSequencer only): the scenario (shipped name or TOML file) the
    FMU plays instead of DEFAULT_SCENARIO. runtime False: pythonfmu's own binaries.
    """
    embedded = embedded_module(model, sequencer_scenario)
    inputs = _inputs_digest(model, source_dir, embedded, runtime)  # before reading them
    dest.mkdir(parents=True, exist_ok=True)
    slave_script = script(model, source_dir)
    modules = dependencies(model, source_dir)
    fmu = dest / f"{model}.fmu"

    def write_fmu(partial: Path) -> None:
        with tempfile.TemporaryDirectory(prefix=f"build_{model}_") as tmp:
            stage = Path(tmp)
            package = stage / "fmu_src"
            package.mkdir()
            root = package_root(source_dir)
            staged = [package / module.relative_to(root) for module in modules]
            for module, copy in zip(modules, staged):
                copy.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(module, copy)
            if embedded is not None:
                staged = sorted([*staged, package / EMBEDDED_SCENARIO])
                (package / EMBEDDED_SCENARIO).write_text(embedded)
            fmi2_build.export(shutil.copy2(slave_script, stage), partial,
                              [package] if modules else [])
            install_runtime(partial, model, inputs, runtime)
            # the documentation reads the staged modules: those the FMU carries
            fmu_docs.add_documentation(partial, slave_script, staged, stage)
            write_archive(partial, archive_entries(partial))  # its entries as the others
    # pythonfmu takes a destination ending in .fmu as the file to write
    write_atomic(fmu, write_fmu, suffix=".fmu")
    osp.write_model_description(fmu)  # <Model>_OspModelDescription.xml beside it, for OSP
    return fmu


def update(model: str, dest: Path = DEFAULT_DEST, source_dir: Path = SOURCE_DIR,
           sequencer_scenario: str | Path | None = None, force: bool = False,
           runtime: bool = True) -> bool:
    """Build dest/<model>.fmu (see `build`) if forced or stale, that is, unless it records
    the digest of its current inputs (`fmu_inputs`); True if it was built. An up-to-date
    FMU whose OSP model description is missing gets it written again."""
    fmu = dest / f"{model}.fmu"
    if not force and not stale(fmu, fmu_inputs(model, source_dir, sequencer_scenario, runtime)):
        if not (dest / f"{model}{osp.SUFFIX}").exists():  # deleted beside an up-to-date FMU
            osp.write_model_description(fmu)
        return False
    build(model, dest, source_dir, sequencer_scenario, runtime)
    return True


def fmu_path(model: str, dest: Path = DEFAULT_DEST, source_dir: Path = SOURCE_DIR,
             sequencer_scenario: str | Path | None = None, runtime: bool = True) -> Path:
    """Path of the built FMU dest/<model>.fmu, built first if stale (`update`)."""
    update(model, dest, source_dir, sequencer_scenario, runtime=runtime)
    return dest / f"{model}.fmu"


def locate(model: str, dest: Path = DEFAULT_DEST) -> Path:
    """The built FMU dest/<model>.fmu for running, never building it: a UserError names the
    command that builds it when it is missing or its recorded inputs are not the current ones
    (`fmu_inputs`)."""
    fmu = dest / f"{model}.fmu"
    if not fmu.exists():
        problem = "is not built"
    elif stale(fmu, fmu_inputs(model)):
        problem = "is out of date with fmu_src"
    else:
        return fmu
    command = ("make fmu" if dest == DEFAULT_DEST
               else f"python -m harness build-fmus --out {dest}")
    raise UserError(f"{fmu} {problem}: build it with `{command}`")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=DEFAULT_DEST, metavar="DIR",
                        help="output folder")
    parser.add_argument(
        "--sequencer-scenario", metavar="NAME_OR_FILE",
        help=f"build only the {SEQUENCER}, playing this scenario (a name of "
             f"harness/scenarios or a TOML file) instead of {DEFAULT_SCENARIO}, into "
             f"DIR/{SEQUENCER}.fmu (default: build every FMU)")
    parser.add_argument("--force", action="store_true",
                        help="rebuild even the FMUs whose inputs have not changed (default: "
                             "build only those whose recorded input digest differs)")


def run(args: argparse.Namespace) -> int:
    for model in MODELS if args.sequencer_scenario is None else (SEQUENCER,):
        built = update(model, args.out, sequencer_scenario=args.sequencer_scenario,
                       force=args.force)
        print(f"{'built    ' if built else 'unchanged'} {args.out / f'{model}.fmu'}")
    return 0
