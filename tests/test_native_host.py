"""A pythonfmu FMU in a host that is not a Python process (README, "Importing the FMUs").

tests/native_host/fmi2_host.c is a minimal FMI 2.0 master in C, as a tool like libcosim's
CLI or OMSimulator is. The FMU's binary does not link libpython: it takes the Python C API
from the process, so such a host must preload libpython and let the interpreter find its
standard library (PYTHONHOME). These tests check both statements of the README.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import fmpy
import pytest
from conftest import open_fmu, run
from fmpy import read_model_description

HOST_SOURCE = Path(__file__).resolve().parent / "native_host" / "fmi2_host.c"
LIBPYTHON = Path(sysconfig.get_config_var("LIBDIR") or "") / (
    sysconfig.get_config_var("LDLIBRARY") or "")
# an unbalanced link (k = 0) swinging from 60 deg for 2 s: outputs that depend on every step
PARAMETERS = {"k": 0.0}
STOP_TIME, STEP_SIZE = 2.0, 1e-3

pytestmark = pytest.mark.skipif(
    shutil.which("cc") is None or not LIBPYTHON.is_file() or not sys.platform.startswith("linux"),
    reason="needs a C compiler and a shared libpython on Linux")


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    exe = tmp_path_factory.mktemp("host") / "fmi2_host"
    include = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["cc", f"-I{include}", str(HOST_SOURCE), "-ldl", "-o", str(exe)], check=True)
    return exe


def host_command(host: Path, fmu: Path, unzipped: Path, outputs: list[str]) -> list[str]:
    md = read_model_description(fmu)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    return [str(host), str(unzipped), md.coSimulation.modelIdentifier, md.guid, str(STOP_TIME),
            str(STEP_SIZE), *(f"{refs[n]}={v}" for n, v in PARAMETERS.items()),
            *(str(refs[n]) for n in outputs)]


def test_native_host_runs_the_fmu_like_fmpy_with_libpython_preloaded(
        host: Path, srb_fmu: Path, tmp_path: Path) -> None:
    unzipped = tmp_path / "fmu"
    zipfile.ZipFile(srb_fmu).extractall(unzipped)
    outputs = ["theta", "omega", "E_t"]
    command = host_command(host, srb_fmu, unzipped, outputs)
    environment = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONHOME")}

    without = subprocess.run(command, env=environment, capture_output=True, text=True)
    assert without.returncode != 0 and "undefined symbol: _Py" in without.stderr

    environment |= {"LD_PRELOAD": str(LIBPYTHON), "PYTHONHOME": sys.base_prefix}
    native = subprocess.run(command, env=environment, capture_output=True, text=True, check=True)
    values = [float(line) for line in native.stdout.split()]

    fmu = open_fmu(srb_fmu, PARAMETERS)
    try:
        expected = run(fmu, round(STOP_TIME / STEP_SIZE), STEP_SIZE, outputs)[-1]
    finally:
        fmu.close()
    assert abs(expected[0] - float(fmu.variables["theta0"].start)) > 0.1  # the link swung
    assert values == pytest.approx(expected.tolist(), rel=1e-12, abs=1e-12)
