"""The FMI 2.0 parts of an FMU's build (`harness.fmu.build` does the rest): pythonfmu's
exporter, the sources of the runtime's FMI 2.0 entry points, where the binary goes in the
archive and the model description's attribute of the FMU's GUID."""

from __future__ import annotations

from pathlib import Path

from pythonfmu.builder import FmuBuilder

from harness import registry

# the runtime's FMI 2.0 entry points and its FMI 2.0 state machine, compiled with its
# version-neutral core (fmu_src/runtime/runtime_core.c)
RUNTIME_SOURCE = registry.SOURCE_DIR / "runtime" / "fmi2_functions.c"
STATE_MACHINE_SOURCE = RUNTIME_SOURCE.with_name("fmi2_states.c")
# the minimal C FMI 2.0 host that runs an FMU outside any Python process (bench, tests)
HOST_SOURCE = Path(__file__).resolve().with_name("fmi2_host.c")
BINARY = "binaries/linux64/{model}.so"  # the runtime's entry in the archive
GUID_ATTRIBUTE = "guid"  # of fmiModelDescription: the GUID the runtime checks


def export(script: Path, dest: Path, project_files: list[Path]) -> None:
    """pythonfmu's FMU of the slave script with the project files (folders or modules) in
    its resources, written to dest: FMU states that can be got, set and serialised, any
    communication step size."""
    FmuBuilder.build_FMU(script, dest=dest, project_files=project_files,
                         canGetAndSetFMUstate=True, canSerializeFMUstate=True,
                         canHandleVariableCommunicationStepSize=True)
