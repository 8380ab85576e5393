"""The FMUs in a host that is not a Python process (docs/using_the_fmus.md).

harness/fmu/fmi2/fmi2_host.c is a minimal FMI 2.0 master in C, as a tool like libcosim's
CLI, fmuCheck or OMSimulator is. It runs here with an empty environment (no LD_PRELOAD,
PYTHONHOME or PYTHONPATH): the FMU's own runtime (fmu_src/runtime/runtime_core.c) must find
Python by itself, with the interpreter the FMU was built with or any CPython 3.8 or later
named by BALANCER_FMU_LIBPYTHON, and give the numbers FMPy gives.
"""

from __future__ import annotations

import ctypes
import functools
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pandas as pd
import pytest
from conftest import FMI_ERROR, FMI_OK, open_fmu, run
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException

from harness import cli, registry
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU

HOST_SOURCE = fmu_build.HOST_SOURCE
STEP_SIZE = 1e-3
# per model: parameters and input start values that make every run move, and the stop time
# (its registration's moving_run)
CASES = {model: ({**r.moving_run.parameters, **r.moving_run.inputs}, r.moving_run.duration)
         for model, r in ((m, registry.registration(m)) for m in fmu_build.MODELS)}
# where shared-library CPythons live: distribution, /usr/local and pyenv installations
LIBPYTHON_GLOBS = ("/usr/lib/x86_64-linux-gnu/libpython3.*.so.1.0",
                   "/usr/lib64/libpython3.*.so.1.0", "/usr/local/lib/libpython3.*.so.1.0",
                   f"{Path.home()}/.pyenv/versions/*/lib/libpython3.*.so.1.0")

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the runtime and the C host are for Linux")


def libpythons() -> list[Path]:
    """Every shared-library CPython 3.8 or later found on the machine, once each."""
    found: dict[Path, Path] = {}
    for pattern in LIBPYTHON_GLOBS:
        for path in sorted(Path("/").glob(pattern.lstrip("/"))):
            match = re.fullmatch(r"libpython3\.(\d+)\.so\.1\.0", path.name)
            if match and int(match.group(1)) >= 8:
                found.setdefault(path.resolve(), path)
    return list(found.values())


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The C host, compiled with the compiler the FMU build uses (no system compiler)."""
    return fmu_build.zig_cc(HOST_SOURCE, tmp_path_factory.mktemp("host") / "fmi2_host")


@pytest.fixture(scope="module")
def unzipped(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every FMU, built if stale, unzipped as an importing tool does."""
    folders = {}
    for model in CASES:
        folders[model] = tmp_path_factory.mktemp(model)
        zipfile.ZipFile(fmu_build.fmu_path(model)).extractall(folders[model])
    return folders


def real_outputs(model: str) -> list[str]:
    md = read_model_description(fmu_build.fmu_path(model))
    return [v.name for v in md.modelVariables if v.causality == "output" and v.type == "Real"]


def host_command(host: Path, model: str, folder: Path,
                 parameters: dict[str, float] | None = None, options: tuple[str, ...] = ()
                 ) -> list[str]:
    """The host's command line: run the model's case and print its Real outputs."""
    md = read_model_description(fmu_build.fmu_path(model))
    refs = {v.name: v.valueReference for v in md.modelVariables}
    case_parameters, stop_time = CASES[model]
    parameters = case_parameters if parameters is None else parameters
    return [str(host), *options, str(folder), model, md.guid, str(stop_time), str(STEP_SIZE),
            *(f"{refs[n]}={v}" for n, v in parameters.items()),
            *(str(refs[n]) for n in real_outputs(model))]


def run_host(command: list[str], environment: dict[str, str]) -> list[float]:
    """The final values the host prints; fails with the host's stderr if it fails."""
    done = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return [float(line) for line in done.stdout.split()]


@functools.cache
def fmpy_final_values(model: str) -> tuple[list[float], list[float]]:
    """The Real outputs after initialisation and at the stop time, run by FMPy."""
    parameters, stop_time = CASES[model]
    outputs = real_outputs(model)
    fmu = open_fmu(fmu_build.fmu_path(model), parameters)
    try:
        initial = [fmu.get(outputs)[name] for name in outputs]
        final = run(fmu, round(stop_time / STEP_SIZE), STEP_SIZE, outputs)[-1]
    finally:
        fmu.close()
    return initial, final.tolist()


def test_the_cases_cover_every_fmu_built() -> None:
    """Against what is on disk, not the registry the cases are made from: every slave script
    (fmu_src/<folders>/<Model>.py, a capitalised name; the bench's floor is no product FMU)
    and every FMU that `make fmu` built into build/fmus (all of them, so none is missed)."""
    floor = registry.SOURCE_DIR / "bench_floor"
    scripts = {path.stem for path in registry.SOURCE_DIR.rglob("*.py")
               if path.stem[0].isupper() and path.parent != floor}
    assert set(CASES) == scripts
    assert {path.stem for path in fmu_build.DEFAULT_DEST.glob("*.fmu")} == set(CASES)


@pytest.mark.parametrize("model", CASES)
def test_every_fmu_runs_without_any_environment_like_fmpy(
        host: Path, unzipped: dict[str, Path], model: str) -> None:
    values = run_host(host_command(host, model, unzipped[model]), environment={})
    initial, expected = fmpy_final_values(model)
    assert not np.allclose(initial, expected, rtol=1e-3, atol=1e-6)  # the run moved
    assert values == pytest.approx(expected, rel=1e-12, abs=1e-12)


# every interpreter with the sequencer (the FMU that once needed 3.11's tomllib) and the
# self-regulating balancer; the other models with every interpreter in `make test-all`
@pytest.mark.parametrize("libpython", libpythons(), ids=str)
@pytest.mark.parametrize("model", [
    model if model in ("ScenarioSequencer", "SelfRegulatingBalancer")
    else pytest.param(model, marks=pytest.mark.slow) for model in CASES])
def test_every_cpython_from_3_8_runs_every_fmu(
        host: Path, unzipped: dict[str, Path], model: str, libpython: Path) -> None:
    values = run_host(host_command(host, model, unzipped[model]),
                      environment={"BALANCER_FMU_LIBPYTHON": str(libpython)})
    assert values == pytest.approx(fmpy_final_values(model)[1], rel=1e-12, abs=1e-12)


def test_a_missing_libpython_gives_null_and_names_what_was_tried(
        host: Path, unzipped: dict[str, Path], tmp_path: Path) -> None:
    missing = tmp_path / "no" / "libpython3.99.so.1.0"
    model = "SelfRegulatingBalancer"
    done = subprocess.run(host_command(host, model, unzipped[model]),
                          env={"BALANCER_FMU_LIBPYTHON": str(missing)}, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 4, done.stderr  # the host's exit status for a NULL instance
    assert "fmi2Instantiate failed" in done.stderr
    assert f"BALANCER_FMU_LIBPYTHON={missing}" in done.stderr
    assert f"{missing}: " in done.stderr  # the path tried, with dlopen's reason


def test_a_libpython_older_than_3_8_is_refused_by_name(
        host: Path, unzipped: dict[str, Path]) -> None:
    old = sorted(Path("/").glob(f"{Path.home()}/.pyenv/versions/3.[67].*/lib/libpython3.*.so.1.0"
                                .lstrip("/")))
    if not old:
        pytest.skip("no CPython 3.6 or 3.7 shared library on this machine")
    model = "SelfRegulatingBalancer"
    done = subprocess.run(host_command(host, model, unzipped[model]),
                          env={"BALANCER_FMU_LIBPYTHON": str(old[0])}, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 4, done.stderr
    assert f"{old[0]}: not a CPython 3.8 or later library (3." in done.stderr


def test_without_the_recorded_libpython_the_linker_search_is_tried(
        host: Path, unzipped: dict[str, Path], tmp_path: Path) -> None:
    """The FMU moved to a machine without its build's interpreter: the runtime falls back on
    the libpython3.X.so.1.0 the dynamic linker finds, and names each one when none loads."""
    model = "SelfRegulatingBalancer"
    folder = tmp_path / model
    shutil.copytree(unzipped[model], folder)
    missing = tmp_path / "gone" / "libpython3.11.so.1.0"
    (folder / "resources" / "python.txt").write_text(f"libpython={missing}\nprefix=/gone\n")
    ldconfig = shutil.which("ldconfig") or "/sbin/ldconfig"
    if not Path(ldconfig).exists():
        pytest.skip("no ldconfig to tell what the dynamic linker finds")
    cache = subprocess.run([ldconfig, "-p"], capture_output=True, text=True).stdout
    system_libpython = any(f"libpython3.{m}.so.1.0 " in cache for m in range(8, 15))
    done = subprocess.run(host_command(host, model, folder), env={}, capture_output=True,
                          text=True, timeout=60)
    if system_libpython:
        assert done.returncode == 0, done.stderr
        values = [float(line) for line in done.stdout.split()]
        assert values == pytest.approx(fmpy_final_values(model)[1], rel=1e-12, abs=1e-12)
    else:
        assert done.returncode == 4, done.stderr
        assert f"{missing}: " in done.stderr
        assert all(f"libpython3.{m}.so.1.0: " in done.stderr for m in range(8, 15))


def test_the_runtime_exports_every_fmi2_function(unzipped: dict[str, Path]) -> None:
    header = (Path(fmpy.__file__).parent / "c-code" / "fmi2Functions.h").read_text()
    names = re.findall(r"#define (fmi2\w+) +fmi2FullName", header)
    binaries = unzipped["SelfRegulatingBalancer"] / "binaries" / "linux64"
    runtime = ctypes.CDLL(str(binaries / "SelfRegulatingBalancer.so"))
    assert "fmi2DoStep" in names and len(names) > 40  # Model Exchange's included
    model_exchange = {"fmi2EnterEventMode", "fmi2NewDiscreteStates",
                      "fmi2EnterContinuousTimeMode", "fmi2CompletedIntegratorStep",
                      "fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives",
                      "fmi2GetEventIndicators", "fmi2GetContinuousStates",
                      "fmi2GetNominalsOfContinuousStates"}
    assert [name for name in names if name not in model_exchange
            and not hasattr(runtime, name)] == []
    assert sorted(p.name for p in binaries.iterdir()) == ["SelfRegulatingBalancer.so"]


# what a linux64 binary may need: glibc's libraries and the dynamic linker, nothing newer than
# glibc 2.17 (RHEL 7, Ubuntu 14.04) and no C++ runtime
ALLOWED_LIBRARIES = {"libc.so.6", "libdl.so.2", "libpthread.so.0", "libm.so.6",
                     "ld-linux-x86-64.so.2"}
OLDEST_GLIBC = (2, 17)


@pytest.mark.skipif(shutil.which("readelf") is None, reason="no readelf (binutils)")
@pytest.mark.parametrize("model", CASES)
def test_the_shipped_binary_runs_on_glibc_2_17_without_a_cpp_runtime(
        unzipped: dict[str, Path], model: str) -> None:
    binary = unzipped[model] / "binaries" / "linux64" / f"{model}.so"
    dynamic = subprocess.run(["readelf", "-d", str(binary)], capture_output=True, text=True,
                             check=True).stdout
    needed = set(re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", dynamic))
    assert "libc.so.6" in needed and needed <= ALLOWED_LIBRARIES, needed
    versions = subprocess.run(["readelf", "-V", str(binary)], capture_output=True, text=True,
                              check=True).stdout
    glibc = {tuple(int(part) for part in v.split("."))
             for v in re.findall(r"Name: GLIBC_([0-9.]+)", versions)}
    assert glibc and max(glibc) <= OLDEST_GLIBC, sorted(glibc)
    assert "GLIBCXX" not in versions and "CXXABI" not in versions


def test_a_python_host_loads_no_second_libpython(srb_fmu: Path) -> None:
    """In FMPy the runtime uses the running interpreter: one libpython mapped, ours."""
    fmu = open_fmu(srb_fmu)
    try:
        maps = Path("/proc/self/maps").read_text()
    finally:
        fmu.close()
    mapped = {line.split()[-1] for line in maps.splitlines() if "/libpython3" in line}
    assert len(mapped) <= 1, mapped  # none when this interpreter is statically linked


def test_a_refused_initialisation_leaves_the_host_running(
        host: Path, unzipped: dict[str, Path]) -> None:
    """J_link = -1 fails initialisation with fmi2Error and the one line naming the parameter;
    the instance is then in the error state (FMI 2.0): the step that follows is refused with
    fmi2Error saying so, the reads are answered (values for debugging), never a crash
    (pythonfmu's binary ended the host here with exit 139)."""
    model = "SelfRegulatingBalancer"
    done = subprocess.run(host_command(host, model, unzipped[model], {"J_link": -1.0}, ("-k",)),
                          env={}, capture_output=True, text=True, timeout=60)
    assert done.returncode == 8, done.stderr  # the host's exit status after failed calls
    statuses = re.findall(r"^(fmi2\w+) returned status (\d)$", done.stderr, re.MULTILINE)
    assert statuses == [("fmi2ExitInitializationMode", "3"), ("fmi2DoStep", "3")]
    (line,) = [line for line in done.stderr.splitlines()
               if "fmi2ExitInitializationMode: ValueError: invalid parameter: J_link" in line]
    assert "status 3" in line
    assert "fmi2DoStep is not allowed in error" in done.stderr  # the refused step says why


def test_in_fmpy_a_refused_initialisation_leaves_the_instance_freeable(srb_fmu: Path) -> None:
    """The same in a Python host, through FMPy's raw calls, down to fmi2FreeInstance (which
    the error state allows, unlike fmi2Terminate)."""
    fmu = CoSimFMU(srb_fmu, instance_name="refused")
    slave, theta = fmu.slave, fmu.references(["theta"])
    calls = [lambda: slave.setupExperiment(startTime=0.0),
             lambda: slave.setReal(fmu.references(["J_link"]), [-1.0]),
             slave.enterInitializationMode, slave.exitInitializationMode,
             lambda: slave.doStep(0.0, 1e-3), lambda: slave.getReal(theta), slave.terminate]
    statuses = []
    for call in calls:
        try:
            call()
            statuses.append(FMI_OK)
        except FMICallException as error:
            statuses.append(error.status)
    assert statuses == [FMI_OK, FMI_OK, FMI_OK, FMI_ERROR, FMI_ERROR, FMI_OK, FMI_ERROR]
    slave.freeInstance()
    shutil.rmtree(fmu.slave.unzipDirectory, ignore_errors=True)


def test_bench_times_each_mechanism_in_the_c_host_and_in_fmpy(tmp_path: Path) -> None:
    """`python -m harness bench --only native_step` (shortened): a row per floor and per
    mechanism FMU with both costs and their ratio, and the ratio to the stock floor."""
    assert cli.main(["bench", "--step-count", "200", "--repeats", "1", "--only", "native_step",
                     "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "native_step.csv")
    assert list(table["model"]) == ["BenchFloor", "BenchFloorRuntime",
                                    *registry.mechanisms()]
    floor = table.set_index("model").us_per_step_c_host["BenchFloor"]
    assert np.allclose(table["ratio_c_host_to_floor"], table["us_per_step_c_host"] / floor)
    assert (table[["us_per_step_c_host", "us_per_step_fmpy"]] > 0).all().all()
    assert np.allclose(table["ratio_c_host_to_fmpy"],
                       table["us_per_step_c_host"] / table["us_per_step_fmpy"])
