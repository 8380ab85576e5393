"""The FMUs' own FMI 2.0 runtime (fmu_src/runtime, fmi2_functions.c on runtime_core.c) under
stress, in a C host.

tests/native_host/fmi2_stress.c loads unzipped FMUs as a long-running importing tool does,
with an empty environment unless stated: load and unload cycles with state round trips
(also under valgrind), thousands of instances and of short-lived host threads (resident
memory must not grow), two host threads stepping at once, instances driven into fmi2Fatal
(no mapping may leak), a printf-formatting logger fed messages full of '%', hostile resource
URIs and arguments, and broken Python installations: every refusal is a NULL instance or a
status with a message, never a crash or a hang.

The probe slaves (tests/data/runtime_slaves) are built into a temporary folder:
RuntimeProbe fails on demand (its Integer input `mode`), NoMethodsOfItsOwn inherits every
method of its class.
"""

from __future__ import annotations

import fcntl
import functools
import os
import re
import shutil
import subprocess
import sys
import textwrap
import urllib.parse
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import FMI_ERROR, SRB
from fmpy import read_model_description
from test_native_host import libpythons

from harness.fmu import build as fmu_build

TESTS = Path(__file__).resolve().parent
STRESS_SOURCE = TESTS / "native_host" / "fmi2_stress.c"
SLAVES = TESTS / "data" / "runtime_slaves"
PROBE, INHERITED = "RuntimeProbe", "NoMethodsOfItsOwn"
TIMEOUT = 60  # [s] for one run of the host: a refusal must never hang
FIFO_TIMEOUT = 20  # [s] a FIFO named as libpython must be refused at once, not opened
VALGRIND_TIMEOUT = 3600
# the probe's messages (tests/data/runtime_slaves/RuntimeProbe.py); the runtime must pass
# them through as text, not as printf formats
PRINTF_MESSAGE = "probe: 70.7 % of the gravity moment, %s %n %d"
VALUE_ERROR = "probe: value error 100 % sure %s %n"
# the probe's `mode` values
NORMAL, RAISE_VALUE_ERROR, RAISE_MEMORY_ERROR, DISCARD, LOG_PRINTF = range(5)
# a message of the host's logger: "[category] instance status N: message"
LOGGED = re.compile(r"^\[([^\]\n]*)\] (\S+) status (\d): ", re.MULTILINE)
# resident memory growth allowed
MAX_BYTES_PER_CYCLE = 1024
MAX_BYTES_PER_THREAD = 200
MAX_NEW_MAPPINGS = 2

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the runtime and the C host are for Linux")


@dataclass(frozen=True)
class Unzipped:
    """An unzipped FMU as the stress host takes it."""

    folder: Path
    model: str
    guid: str
    refs: dict[str, int]

    def args(self, *options: str) -> list[str]:
        """DIR MODEL GUID and the FMU's options (r:VR, d:VR=VALUE, i:VR=VALUE)."""
        return [str(self.folder), self.model, self.guid, *options]

    @property
    def resources(self) -> Path:
        return self.folder / "resources"


def unzip(fmu: Path, folder: Path) -> Unzipped:
    zipfile.ZipFile(fmu).extractall(folder)
    md = read_model_description(fmu)
    return Unzipped(folder, md.coSimulation.modelIdentifier, md.guid,
                    {v.name: v.valueReference for v in md.modelVariables})


@pytest.fixture(scope="module")
def stress(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The stress host, compiled with the compiler the FMU build uses."""
    return fmu_build.zig_cc(STRESS_SOURCE, tmp_path_factory.mktemp("stress") / "fmi2_stress",
                            "-lpthread", "-ldl")


@pytest.fixture(scope="module")
def probe_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The probe slaves built (as `make fmu` builds the shipped ones) into a temporary folder."""
    dest = tmp_path_factory.mktemp("runtime_slaves")
    return {model: fmu_build.build(model, dest, SLAVES) for model in (PROBE, INHERITED)}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory, probe_fmus: dict[str, Path]
         ) -> dict[str, Unzipped]:
    """The SelfRegulatingBalancer and the probes, unzipped."""
    paths = {SRB: fmu_build.fmu_path(SRB), **probe_fmus}
    return {model: unzip(path, tmp_path_factory.mktemp(model)) for model, path in paths.items()}


@pytest.fixture(scope="module")
def hostile(tmp_path_factory: pytest.TempPathFactory) -> Unzipped:
    """The SelfRegulatingBalancer unzipped into a folder whose name has 'ü', '+' and a space."""
    folder = tmp_path_factory.mktemp("hostile") / "Fahrstuhl ü+1 Gegengewicht"
    return unzip(fmu_build.fmu_path(SRB), folder)


def stress_run(stress: Path, *args: str, env: dict[str, str] | None = None,
               timeout: float = TIMEOUT) -> subprocess.CompletedProcess[str]:
    """One run of the stress host, with an empty environment unless env is given."""
    return subprocess.run([str(stress), *args], env={} if env is None else env,
                          capture_output=True, text=True, timeout=timeout)


def stress_ok(stress: Path, *args: str, env: dict[str, str] | None = None) -> str:
    """The stdout of a run that must succeed (exit 0); fails with its stderr otherwise."""
    done = stress_run(stress, *args, env=env)
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stderr[-4000:]}"
    return done.stdout


def messages(stderr: str) -> list[tuple[int, str]]:
    """The (status, message) of every message the host's logger wrote, a message running
    to the next one or to the end (so a message may span lines)."""
    starts = list(LOGGED.finditer(stderr))
    ends = [m.start() for m in starts[1:]] + [len(stderr)]
    return [(int(m.group(3)), stderr[m.end():end].rstrip("\n")) for m, end in zip(starts, ends)]


def measure(stdout: str, key: str) -> float:
    match = re.search(rf"^{key} (\S+)$", stdout, re.MULTILINE)
    assert match, stdout
    return float(match.group(1))


def instantiate(stress: Path, fmu: Unzipped, *options: str, env: dict[str, str] | None = None,
                timeout: float = TIMEOUT) -> subprocess.CompletedProcess[str]:
    """`fmi2_stress instantiate`; the host must exit 0 (a crash is an exit status above 0)."""
    done = stress_run(stress, "instantiate", *fmu.args(), *options, env=env, timeout=timeout)
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stdout}\n{done.stderr[-4000:]}"
    return done


def assert_refused(done: subprocess.CompletedProcess[str]) -> str:
    """The instance is NULL and the FMU said why on stderr; that stderr."""
    assert done.stdout.splitlines()[:1] == ["instance NULL"], done.stdout + done.stderr
    assert messages(done.stderr) or done.stderr.strip(), "refused without a message"
    return done.stderr


def assert_runs(done: subprocess.CompletedProcess[str]) -> None:
    assert done.stdout.splitlines()[:1] == ["instance OK"], done.stdout + done.stderr
    assert "run OK" in done.stdout.splitlines(), done.stdout + done.stderr


def srb_moving(fmu: Unzipped) -> list[str]:
    """Options that make the SelfRegulatingBalancer move (its registration's moving run:
    k = 0) and read its angle, speed and slider position."""
    return [f"d:{fmu.refs['k']}=0", *(f"r:{fmu.refs[n]}" for n in ("theta", "omega", "x"))]


def probe_mode(fmu: Unzipped, mode: int) -> str:
    return f"i:{fmu.refs['mode']}={mode}"


# --- load/unload cycles -------------------------------------------------------------------


def test_cycles_of_two_fmus_load_run_save_restore_and_unload(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    probe = fmus[PROBE]
    stdout = stress_ok(stress, "cycles", "5", "200", *fmus[SRB].args(),
                       *probe.args(f"d:{probe.refs['u']}=2", f"r:{probe.refs['y']}"))
    assert stdout.splitlines() == ["cycles done"]


def valgrind_command(stress: Path, *args: str) -> list[str]:
    """The stress host under valgrind: every memory error and every definite leak fails it
    (exit status 99); only definite leaks are listed (Python keeps much "possibly lost").
    Run by `python -m pytest -m slow tests/test_runtime.py -k valgrind`."""
    return ["valgrind", "--error-exitcode=99", "--leak-check=full",
            "--errors-for-leak-kinds=definite", "--show-leak-kinds=definite", str(stress),
            *args]


VALGRIND_ENV = {"PYTHONMALLOC": "malloc"}  # every allocation seen by valgrind


def recorded_libpython(fmu: Unzipped) -> Path | None:
    """The libpython the FMU was built with (resources/python.txt), if it records one."""
    record = (fmu.resources / "python.txt").read_text()
    found = re.search(r"^libpython=(.+)$", record, re.MULTILINE)
    return Path(found.group(1)) if found else None


def interpreter_of(libpython: Path) -> Path | None:
    """The python3.X program of a CPython 3.8 or later shared library (PREFIX/bin beside
    PREFIX/lib, or /usr/bin for a distribution's), if it is there."""
    minor = re.fullmatch(r"libpython3\.(\d+)\.so\.1\.0", libpython.name)
    prefix = libpython.parent.parent if libpython.parent.name == "lib" else Path("/usr")
    python = prefix / "bin" / f"python3.{minor.group(1)}" if minor else None
    return python if python is not None and int(minor.group(1)) >= 8 and python.exists() \
        else None


@functools.cache
def clean_under_valgrind(libpython: Path) -> bool:
    """Whether the interpreter of libpython runs an import without any valgrind error.
    CPython 3.11.7, for one, reads an uninitialised digit in int.from_bytes: hundreds of
    errors before any FMU code runs."""
    python = interpreter_of(libpython)
    if python is None:
        return False
    done = subprocess.run(["valgrind", "--error-exitcode=99", str(python), "-c",
                           "import importlib.util, json"], env=VALGRIND_ENV,
                          capture_output=True, text=True, timeout=VALGRIND_TIMEOUT)
    return done.returncode == 0


def valgrind_environment(fmu: Unzipped) -> dict[str, str]:
    """VALGRIND_ENV, and BALANCER_FMU_LIBPYTHON naming a CPython clean under valgrind when
    the FMU's own interpreter is not (its errors are not the runtime's); skips without one."""
    own = recorded_libpython(fmu)
    if own is not None and clean_under_valgrind(own):
        return dict(VALGRIND_ENV)
    others = sorted({p.resolve() for p in libpythons()})
    for libpython in others:
        if libpython != (own.resolve() if own else None) and clean_under_valgrind(libpython):
            return {**VALGRIND_ENV, "BALANCER_FMU_LIBPYTHON": str(libpython)}
    pytest.skip(f"no CPython runs clean under valgrind here (the FMU's: {own})")


def valgrind_report(stderr: str) -> str:
    """valgrind's first error records and its summaries, for a failure message."""
    lines = stderr.splitlines()
    summary = [line for line in lines if re.search(r"(SUMMARY|lost|reachable):", line)]
    return "\n".join(lines[:120] + ["..."] + summary[-8:])


@pytest.mark.slow
def test_valgrind_finds_no_error_and_no_definite_leak_in_50_cycles(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed")
    probe = fmus[PROBE]
    done = subprocess.run(
        valgrind_command(stress, "cycles", "50", "200", *fmus[SRB].args(),
                         *probe.args(f"d:{probe.refs['u']}=2")),
        env=valgrind_environment(probe), capture_output=True, text=True,
        timeout=VALGRIND_TIMEOUT)
    report = valgrind_report(done.stderr)
    assert done.returncode == 0, f"exit {done.returncode}\n{report}"
    assert done.stdout.splitlines() == ["cycles done"]
    assert "ERROR SUMMARY: 0 errors" in done.stderr, report
    lost = re.findall(r"definitely lost: ([\d,]+) bytes", done.stderr)
    assert all(n == "0" for n in lost), report


@pytest.mark.slow
def test_valgrind_finds_no_error_and_no_definite_leak_in_model_exchange_cycles(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    """20 Model Exchange life cycles (load, integrate 200 steps with events, state round
    trip, hostile calls, free, unload) under valgrind: no error, no definite leak."""
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed")
    done = subprocess.run(
        valgrind_command(stress, "me-cycles", "20", "200", SRB_NX, SRB_NZ, *fmus[SRB].args()),
        env=valgrind_environment(fmus[SRB]), capture_output=True, text=True,
        timeout=VALGRIND_TIMEOUT)
    report = valgrind_report(done.stderr)
    assert done.returncode == 0, f"exit {done.returncode}\n{report}"
    assert done.stdout.splitlines() == ["me cycles done"]
    assert "ERROR SUMMARY: 0 errors" in done.stderr, report
    lost = re.findall(r"definitely lost: ([\d,]+) bytes", done.stderr)
    assert all(n == "0" for n in lost), report


# --- resident memory ----------------------------------------------------------------------


@pytest.mark.parametrize(("model", "cycles"), [
    (PROBE, 300), pytest.param(PROBE, 2000, marks=pytest.mark.slow),
    # a mechanism's interpreter heap settles later (about 1.7 kB per cycle over the first 300)
    pytest.param(SRB, 2000, marks=pytest.mark.slow)])
def test_instance_cycles_do_not_grow_resident_memory(
        stress: Path, fmus: dict[str, Unzipped], model: str, cycles: int) -> None:
    stdout = stress_ok(stress, "rss", str(cycles), *fmus[model].args())
    assert measure(stdout, "rss_bytes_per_cycle") <= MAX_BYTES_PER_CYCLE


@pytest.mark.parametrize(("model", "cycles"), [
    (PROBE, 300), pytest.param(SRB, 2000, marks=pytest.mark.slow)])
def test_load_and_unload_cycles_do_not_grow_resident_memory(
        stress: Path, fmus: dict[str, Unzipped], model: str, cycles: int) -> None:
    """dlopen, instantiate, 10 steps, free, dlclose: each load of the runtime used to make
    its Python helper anew and keep it (about 5 kB a cycle for the probe, 6 kB for the
    SelfRegulatingBalancer); the helper is the process's now, made once."""
    stdout = stress_ok(stress, "reload", str(cycles), *fmus[model].args())
    assert measure(stdout, "rss_bytes_per_reload") <= MAX_BYTES_PER_CYCLE


@pytest.mark.parametrize("threads", [2000, pytest.param(20000, marks=pytest.mark.slow)])
def test_short_lived_host_threads_do_not_grow_resident_memory(
        stress: Path, fmus: dict[str, Unzipped], threads: int) -> None:
    stdout = stress_ok(stress, "short-threads", str(threads), *fmus[PROBE].args())
    assert measure(stdout, "rss_bytes_per_thread") <= MAX_BYTES_PER_THREAD


# --- host threads -------------------------------------------------------------------------


def thread_values(stdout: str) -> list[tuple[int, float]]:
    found = re.findall(r"^thread (\d) value (\S+)$", stdout, re.MULTILINE)
    return [(int(thread), float(value)) for thread, value in found]


@pytest.mark.parametrize("pair", ["two balancers", "a balancer and a probe"])
def test_two_host_threads_step_at_once_as_one_thread_does(
        stress: Path, fmus: dict[str, Unzipped], pair: str) -> None:
    srb, probe = fmus[SRB], fmus[PROBE]
    second = (srb.args(*srb_moving(srb)) if pair == "two balancers" else
              probe.args(f"d:{probe.refs['u']}=3", f"r:{probe.refs['y']}"))
    fmu_args = [*srb.args(*srb_moving(srb)), *second]
    threaded = thread_values(stress_ok(stress, "threads", *fmu_args))
    serial = thread_values(stress_ok(stress, "serial", *fmu_args))
    assert [thread for thread, _ in threaded] == [0, 0, 0, *[1] * (len(threaded) - 3)]
    assert threaded == serial
    assert serial[0][1] != 0.0  # the balancer moved
    if pair != "two balancers":
        assert serial[-1] == (1, 3.0)


# --- fmi2Fatal ----------------------------------------------------------------------------


def test_fatal_instances_are_refused_and_freed_without_leaking_mappings(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    probe = fmus[PROBE]
    stdout = stress_ok(stress, "fatal", "500", *probe.args(probe_mode(probe,
                                                                       RAISE_MEMORY_ERROR)))
    first, last = measure(stdout, "maps_first"), measure(stdout, "maps_last")
    assert last - first <= MAX_NEW_MAPPINGS, stdout


# --- messages -----------------------------------------------------------------------------


def test_a_logged_message_reaches_a_printf_logger_as_its_text(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    """The runtime passes every message as a format without directives (each % as %%): a
    host's logger that formats it like printf prints the message exactly."""
    probe = fmus[PROBE]
    done = instantiate(stress, probe, probe_mode(probe, LOG_PRINTF))
    assert_runs(done)
    assert PRINTF_MESSAGE in [message for _, message in messages(done.stderr)], done.stderr


@pytest.mark.parametrize("depth", [1, -1], ids=["one level", "no limit"])
def test_a_logger_that_calls_the_fmu_passes_each_message_on_once(
        stress: Path, fmus: dict[str, Unzipped], depth: int) -> None:
    """The probe logs a Warning in its step; the host's logger calls fmi2GetReal for every
    message it gets, one level deep or without a limit. The nested call used to pass the
    same queued message on again: logged twice with one level, and without a limit the
    host died of SIGSEGV (endless recursion). Each message now reaches the logger once."""
    probe = fmus[PROBE]
    done = stress_run(stress, "reentrant", str(depth),
                      *probe.args(probe_mode(probe, LOG_PRINTF), f"r:{probe.refs['y']}"))
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stderr[-2000:]}"
    assert done.stdout.splitlines() == ["doStep status 0"]
    assert [message for _, message in messages(done.stderr)] == [PRINTF_MESSAGE]


def test_a_logger_whose_calls_log_again_is_cut_off(stress: Path,
                                                   fmus: dict[str, Unzipped]) -> None:
    """A logger that calls fmi2GetReal with an unknown value reference for every message:
    each call fails with a new message, which calls the logger again. The recursion is cut
    off 8 calls deep instead of running out of stack."""
    probe = fmus[PROBE]
    done = stress_run(stress, "reentrant", "-1", *probe.args(probe_mode(probe, LOG_PRINTF),
                                                             "r:99999"))
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stderr[-2000:]}"
    logged = messages(done.stderr)
    assert logged[0] == (1, PRINTF_MESSAGE)
    assert 1 < len(logged) <= 9 and all(status == FMI_ERROR for status, _ in logged[1:])


def test_an_exception_in_do_step_is_an_error_with_its_message(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    probe = fmus[PROBE]
    done = instantiate(stress, probe, probe_mode(probe, RAISE_VALUE_ERROR))
    assert f"doStep status {FMI_ERROR}" in done.stdout.splitlines(), done.stdout + done.stderr
    logged = [message for _, message in messages(done.stderr) if VALUE_ERROR in message]
    assert len(logged) == 1, done.stderr
    assert "ValueError" in logged[0]


def test_a_huge_nvr_is_an_error_not_fatal(stress: Path, fmus: dict[str, Unzipped]) -> None:
    """fmi2GetReal with nvr = 2^40 (a host's mistake) used to end in a MemoryError: fmi2Fatal,
    the instance dead for good. nvr beyond the FMU's variables is refused before any array
    is read: fmi2Error naming it (fmi2SetReal alike), and the instance answers a read
    afterwards (in the error state)."""
    probe = fmus[PROBE]
    done = stress_run(stress, "huge-nvr", *probe.args(f"r:{probe.refs['y']}"))
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.splitlines() == [f"setReal huge status {FMI_ERROR}",
                                        f"getReal huge status {FMI_ERROR}", "getReal status 0"]
    logged = [message for status, message in messages(done.stderr) if status == FMI_ERROR]
    assert logged == [f"fmi2{call}: nvr = {2**40} value references, more than the "
                      f"{len(probe.refs)} variables of this FMU" for call in ("SetReal", "GetReal")]


# --- resource URIs ------------------------------------------------------------------------


GOOD_URIS = {
    "percent-encoded": lambda p: "file://" + urllib.parse.quote(str(p)),
    "raw": lambda p: "file://" + str(p),
    "file:/abs": lambda p: "file:" + str(p),
    "file:/abs encoded": lambda p: "file:" + urllib.parse.quote(str(p)),
    "localhost": lambda p: "file://localhost" + str(p),
    "localhost encoded": lambda p: "file://localhost" + urllib.parse.quote(str(p)),
}


@pytest.mark.parametrize("form", GOOD_URIS)
def test_every_form_of_a_file_uri_finds_the_resources(
        stress: Path, hostile: Unzipped, form: str) -> None:
    uri = GOOD_URIS[form](hostile.resources)
    assert_runs(instantiate(stress, hostile, "--uri", uri))


BAD_URIS = {
    "missing folder": lambda p: "file://" + urllib.parse.quote(str(p / "missing")),
    "no slavemodule.txt": lambda p: "file://" + urllib.parse.quote(str(p.parent)),
    "http": lambda p: "http://host/x",
    "other host": lambda p: "file://otherhost" + urllib.parse.quote(str(p)),
    "empty": lambda p: "",
    "relative": lambda p: "relative/path",
}


@pytest.mark.parametrize("case", BAD_URIS)
def test_an_unusable_resource_uri_gives_null_with_a_message(
        stress: Path, hostile: Unzipped, case: str) -> None:
    assert_refused(instantiate(stress, hostile, "--uri", BAD_URIS[case](hostile.resources)))


# --- arguments ----------------------------------------------------------------------------


@pytest.mark.parametrize("flag", ["--null-name", "--null-guid", "--null-uri"])
def test_a_null_argument_gives_null_with_a_message(
        stress: Path, fmus: dict[str, Unzipped], flag: str) -> None:
    assert_refused(instantiate(stress, fmus[SRB], flag))


def test_model_exchange_of_a_co_simulation_slave_is_refused_naming_co_simulation(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    stderr = assert_refused(instantiate(stress, fmus[PROBE], "--type", "me"))
    assert re.search(r"co-?simulation only", stderr, re.IGNORECASE), stderr


# the SelfRegulatingBalancer's numbers of continuous states and event indicators
SRB_NX, SRB_NZ = "8", "3"
# what the runtime answers each hostile Model Exchange call of the stress host's me-cycles
HOSTILE_ME_MESSAGES = (
    "fmi2GetDerivatives: nx = 9 is not this FMU's number of continuous states, 8",
    "fmi2GetEventIndicators: ni = 4 is not this FMU's number of event indicators, 3",
    "fmi2SetContinuousStates: the slave's arguments: a NULL array",
    "continuous states refused, not finite: theta = nan",
    "time = -1.0 s is before the last event",
    "fmi2DoStep is not allowed in Continuous-Time Mode (FMI 2.0 Model Exchange has no such "
    "call)",
    "fmi2NewDiscreteStates is not allowed in Continuous-Time Mode (FMI 2.0 Model Exchange: "
    "only in Event Mode)",
)


def test_model_exchange_life_cycles_refuse_hostile_calls_with_messages(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    """Model Exchange instances integrated with their events (explicit Euler, an event every
    0.1 s), a state round trip, then out-of-sequence calls, a wrong nx and ni, NaN and NULL
    states, a time before the last event and a Co-Simulation call: each fmi2Error with a
    message (the FMU state taken before each puts the instance back), the process alive and
    the instance usable after them (the host exits 1 on any other status)."""
    done = stress_run(stress, "me-cycles", "2", "300", SRB_NX, SRB_NZ, *fmus[SRB].args())
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stderr[-4000:]}"
    assert done.stdout.splitlines() == ["me cycles done"]
    logged = [text for status, text in messages(done.stderr) if status == FMI_ERROR]
    for expected in HOSTILE_ME_MESSAGES:
        assert sum(expected in text for text in logged) == 2, (expected, logged)


def test_a_wrong_guid_is_refused_naming_both_guids(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    wrong = "00000000-0000-0000-0000-000000000000"
    stderr = assert_refused(instantiate(stress, fmus[SRB], "--guid", wrong))
    assert wrong in stderr and fmus[SRB].guid in stderr, stderr


def test_a_step_after_terminate_is_an_error_with_a_message(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    done = instantiate(stress, fmus[PROBE], "--after-terminate")
    assert_runs(done)
    assert f"doStep after terminate status {FMI_ERROR}" in done.stdout.splitlines(), done.stdout
    assert messages(done.stderr), "no message"  # the probe logs nothing else


# --- broken Python installations ----------------------------------------------------------


def other_python_prefix() -> Path | None:
    """A pyenv CPython 3.8 installation, unless it is this interpreter's."""
    found = sorted((Path.home() / ".pyenv" / "versions").glob("3.8.*"))
    found = [p for p in found if p.resolve() != Path(sys.base_prefix).resolve()]
    return found[0] if found else None


@pytest.mark.parametrize("case", ["missing folder", "regular file", "Python 3.8 prefix"])
def test_a_wrong_pythonhome_gives_null_naming_it(
        stress: Path, fmus: dict[str, Unzipped], tmp_path: Path, case: str) -> None:
    if case == "missing folder":
        home = tmp_path / "no" / "python"
    elif case == "regular file":
        home = tmp_path / "python"
        home.write_text("not a Python installation\n")
    else:
        home = other_python_prefix()
        if home is None:
            pytest.skip("no other CPython's prefix (~/.pyenv/versions/3.8.*)")
    stderr = assert_refused(instantiate(stress, fmus[SRB], env={"PYTHONHOME": str(home)}))
    assert "PYTHONHOME" in stderr and str(home) in stderr, stderr


def test_a_fifo_named_as_libpython_is_refused_without_opening_it(
        stress: Path, fmus: dict[str, Unzipped], tmp_path: Path) -> None:
    fifo = tmp_path / "libpython3.11.so.1.0"
    os.mkfifo(fifo)
    try:
        done = instantiate(stress, fmus[SRB], env={"BALANCER_FMU_LIBPYTHON": str(fifo)},
                           timeout=FIFO_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the host hung for {FIFO_TIMEOUT} s on a FIFO named as libpython")
    stderr = assert_refused(done)
    assert str(fifo) in stderr, stderr


def test_the_host_environment_is_left_as_it_was(stress: Path,
                                                fmus: dict[str, Unzipped]) -> None:
    """With an empty environment the runtime starts the FMU's CPython with the prefix
    recorded at build time as its home. It used to setenv PYTHONHOME for that, which stayed
    set for the host's children: a child starting a CPython of another version died (No
    module named 'encodings'). The home now goes through PyConfig: the environment is the
    host's, and the child runs."""
    probe = fmus[PROBE]
    own = recorded_libpython(probe)
    if own is None:
        pytest.skip("the FMU records no libpython (its prefix is not passed then)")
    version = re.search(r"^version=(\d+\.\d+)", (probe.resources / "python.txt").read_text(),
                        re.MULTILINE)
    others = [python for python in map(interpreter_of, libpythons())
              if python is not None and version and python.name != f"python{version[1]}"]
    if not others:
        pytest.skip("no CPython of another version than the FMU's to start as a child")
    done = stress_run(stress, "environment", *probe.args(), "--", str(others[0]), "-c",
                      "import encodings")
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.splitlines() == ["environment unchanged", "child exit 0"]


def test_the_recorded_prefix_is_the_home_of_the_python_it_starts(
        stress: Path, fmus: dict[str, Unzipped], tmp_path: Path) -> None:
    """The prefix in resources/python.txt reaches the CPython the runtime starts as its home
    (through PyConfig): an empty folder recorded there keeps it from finding its standard
    library, and the instance is refused naming that folder."""
    probe = fmus[PROBE]
    if recorded_libpython(probe) is None:
        pytest.skip("the FMU records no libpython")
    folder = tmp_path / "probe"
    shutil.copytree(probe.folder, folder)
    empty = tmp_path / "empty prefix"
    empty.mkdir()
    record = folder / "resources" / "python.txt"
    record.write_text(re.sub(r"^prefix=.*$", f"prefix={empty}", record.read_text(),
                             flags=re.MULTILINE))
    moved = Unzipped(folder, probe.model, probe.guid, probe.refs)
    stderr = assert_refused(instantiate(stress, moved))
    assert f"PYTHONHOME={empty} (the prefix recorded at build time)" in stderr, stderr


CONFIG_HOME_PROBE = """
#include <Python.h>
#include <stddef.h>
#include <stdio.h>
int main(void) { printf("%d %zu\\n", PY_MINOR_VERSION, offsetof(PyConfig, home)); return 0; }
"""


def include_folder(libpython: Path) -> Path | None:
    """The folder of Python.h of a CPython shared library, if its headers are installed."""
    minor = re.fullmatch(r"libpython(3\.\d+)\.so\.1\.0", libpython.name)
    prefix = libpython.parent.parent if libpython.parent.name == "lib" else Path("/usr")
    folder = prefix / "include" / f"python{minor.group(1)}" if minor else None
    return folder if folder is not None and (folder / "Python.h").is_file() else None


def test_the_runtime_knows_where_every_cpython_keeps_its_home(tmp_path: Path) -> None:
    """The runtime passes the recorded home through PyConfig.home, whose offset differs by
    CPython version: its table (config_home_offset) against offsetof in the headers of every
    CPython 3.8 or later installed here."""
    table = dict(re.findall(r"\[(\d+)\] = (\d+)", re.search(
        r"config_home_offset\(void\) \{(.*?)\};", fmu_build.RUNTIME_CORE_SOURCE.read_text(),
        re.DOTALL)[1]))
    source = tmp_path / "home.c"
    source.write_text(CONFIG_HOME_PROBE)
    compiler = shutil.which("cc")  # the system's: a distribution's headers need its libc's
    if compiler is None:
        pytest.skip("no system C compiler")
    checked = {}
    for libpython in libpythons():
        folder = include_folder(libpython)
        if folder is None:
            continue
        probe = tmp_path / f"home_{libpython.name}"
        subprocess.run([compiler, f"-I{folder}", str(source), "-o", str(probe)], check=True)
        minor, offset = subprocess.run([str(probe)], capture_output=True, text=True,
                                       check=True).stdout.split()
        checked[minor] = offset
        assert table.get(minor) == offset, (libpython, minor, offset)
    if not checked:
        pytest.skip("no CPython headers installed")


# --- fork ---------------------------------------------------------------------------------


@pytest.mark.parametrize("pair", ["one FMU", "two FMUs"])
def test_a_fork_while_another_thread_is_inside_an_fmu_call_leaves_a_working_child(
        stress: Path, fmus: dict[str, Unzipped], pair: str) -> None:
    """A host forks 8 times while a second thread steps an instance; each child steps and
    reads another instance (of the same FMU, or of a second FMU: two copies of the runtime).
    Every child used to wait for ever on the GIL the other thread held in the parent; the
    runtime now takes the GIL around every fork (PyOS_BeforeFork, PyOS_AfterFork_*). Once the
    FMUs are unloaded, a fork calls none of their handlers (it would crash)."""
    probe, srb = fmus[PROBE], fmus[SRB]
    children = probe.args(f"r:{probe.refs['y']}") if pair == "one FMU" else srb.args(
        f"r:{srb.refs['theta']}")
    done = stress_run(stress, "fork", "8", *probe.args(f"r:{probe.refs['y']}"),
                      *(children if pair == "two FMUs" else ()), timeout=200)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.splitlines() == ["children finished 8 of 8",
                                        "fork after unloading: OK"]


# --- a host with a CPython of its own ------------------------------------------------------


def beside_cases() -> list:
    """(libpython, binding, started) for every CPython 3.8 or later here other than the one
    the FMUs are built with: the host opens it RTLD_LOCAL, binding lazily or now, and starts
    it or not. Debian's 3.11 and a 3.12, the two the hostile round crashed with, in the fast
    suite; the others in `make test-all`."""
    own = fmu_build.libpython()
    own = own.resolve() if own else None
    cases = []
    for libpython in libpythons():
        if libpython.resolve() == own:
            continue
        fast = libpython.name == "libpython3.12.so.1.0" or str(libpython).startswith("/usr/")
        for binding in ("lazy", "now"):
            for started in ("start", "idle"):
                marks = () if fast and binding == "lazy" else (pytest.mark.slow,)
                cases.append(pytest.param(libpython, binding, started, marks=marks,
                                          id=f"{libpython}-{binding}-{started}"))
    return cases


@pytest.mark.parametrize(("libpython", "binding", "started"), beside_cases())
def test_a_host_holding_another_cpython_runs_the_fmu_in_it(
        stress: Path, fmus: dict[str, Unzipped], libpython: Path, binding: str,
        started: str) -> None:
    """A C host that opened a CPython of its own RTLD_LOCAL (as a plugin does), started or
    not. The runtime used to miss it, load the FMU's own CPython RTLD_GLOBAL beside it, and
    the two interpreters' symbols crossed: SIGSEGV with 3.12, "double free or corruption"
    with Debian's 3.11. It now finds the host's CPython (dl_iterate_phdr), makes its symbols
    visible to its extension modules, starts it if the host has not, and runs the FMU in it;
    the host's own Python code runs before and after."""
    probe = fmus[PROBE]
    done = stress_run(stress, "beside", str(libpython), binding, started,
                      *probe.args(f"d:{probe.refs['u']}=3", f"r:{probe.refs['y']}"))
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stderr[-2000:]}"
    assert done.stdout.splitlines() == ["value 3", "host python OK"]


def test_a_host_holding_a_cpython_older_than_3_8_is_refused_by_name(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    """With a CPython 3.6 or 3.7 in the process the runtime can use none and loads no second
    one beside it: the instance is NULL, the message names the library in the process."""
    old = sorted(Path("/").glob(f"{Path.home()}/.pyenv/versions/3.[67].*/lib/libpython3.*.so.1.0"
                                .lstrip("/")))
    if not old:
        pytest.skip("no CPython 3.6 or 3.7 shared library on this machine")
    done = stress_run(stress, "beside", str(old[0]), "lazy", "idle", *fmus[PROBE].args())
    assert done.returncode == 1, done.stdout + done.stderr[-2000:]
    assert "fmi2Instantiate returned NULL" in done.stderr
    assert f"{old[0]} (CPython 3." in done.stderr
    assert "loads no second interpreter beside it" in done.stderr


# --- a Python host ------------------------------------------------------------------------


INHERITED_RUNS = textwrap.dedent("""
    import shutil
    import sys
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    path = sys.argv[1]
    md = read_model_description(path)
    folder = extract(path)
    (t,) = [v.valueReference for v in md.modelVariables if v.name == "t"]
    for k in range(100):
        slave = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                          modelIdentifier=md.coSimulation.modelIdentifier,
                          instanceName=f"inherited{k}")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.doStep(0.0, 1e-3)
        assert slave.getReal([t]) == [1e-3], slave.getReal([t])
        slave.terminate()
        slave.freeInstance()
    shutil.rmtree(folder, ignore_errors=True)
    print("done")
""")


def test_a_class_with_only_inherited_methods_runs_in_fmpy(probe_fmus: dict[str, Path]) -> None:
    done = subprocess.run([sys.executable, "-c", INHERITED_RUNS, str(probe_fmus[INHERITED])],
                          capture_output=True, text=True, timeout=TIMEOUT)
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stderr[-4000:]}"
    assert done.stdout.splitlines() == ["done"]


@pytest.mark.slow  # a whole cosim run; the URI forms are tested above in the C host
def test_cosim_runs_with_a_temporary_folder_whose_name_needs_percent_encoding(
        tmp_path: Path) -> None:
    """FMPy extracts each FMU under TMPDIR and percent-encodes the resource URI: a "ü", a "+"
    and a space in that folder's name (pythonfmu's binary decoded only %20: exit 139)."""
    temporary = tmp_path / "tmp ü+x"
    temporary.mkdir()
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-m", "harness", "cosim", "--scenario", "franchetti2021",
         "--variants", "unbalanced", "--workers", "1", "--out", str(out)],
        env={**os.environ, "TMPDIR": str(temporary)}, capture_output=True, text=True,
        timeout=300)
    assert done.returncode == 0, done.stderr
    assert (out / "franchetti2021" / "summary.csv").is_file()


def test_another_process_holding_the_libpython_file_does_not_block_the_start(
        stress: Path, fmus: dict[str, Unzipped]) -> None:
    """Starting Python is serialised within one process only: a lock on the libpython file
    (as the runtime once took, shared by every process of the machine) held by this process
    must not keep a C host from instantiating (it waited for as long as the lock was held)."""
    probe = fmus[PROBE]
    libpython = recorded_libpython(probe)
    if libpython is None:
        pytest.skip("the FMU records no libpython")
    with libpython.open("rb") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert_runs(instantiate(stress, probe, env={}, timeout=FIFO_TIMEOUT))
