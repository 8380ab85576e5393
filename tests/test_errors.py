"""Our error types across processes, and FMU failures raised where the FMU is freed.

An error raised in a worker process (cosim --workers, a sweep's Dask worker) reaches the
parent pickled; one that cannot be unpickled would break the whole process pool.
"""

from __future__ import annotations

import importlib
import io
import pickle
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import fmu_src
import harness
from fmu_src.integration import SubstepBoundError
from fmu_src.parameters import DomainError
from harness.errors import UserError
from harness.fmu.loader import CoSimFMU, FMICallException, FMUCallError, LogMessage
from harness.report.template import TemplateError
from harness.sweeps.paths import PathError, RefusedValueError
from tests.conftest import FMI_ERROR, SRB, bundled, open_fmu

ROOT = Path(__file__).resolve().parents[1]


def fmu_call_error() -> FMUCallError:
    return FMUCallError(FMICallException("fmi2DoStep", FMI_ERROR), SRB,
                        [LogMessage("Error", "logStatusError", "k = -5.0 N/m is outside")])


EXAMPLES = {  # one instance of every error type defined in harness/ and fmu_src/
    UserError: UserError("--step = 0 s is outside [1e-06, 35]"),
    PathError: PathError("parameters.x names nothing"),
    RefusedValueError: RefusedValueError("k = -5 is outside [0, inf)"),
    SubstepBoundError: SubstepBoundError("more than 20,000 sub-steps"),
    DomainError: DomainError("the linkage cannot be assembled"),
    FMUCallError: fmu_call_error(),
    TemplateError: TemplateError("{number(ideal.E_drawn.c)}: AttributeError: c"),
}


def defined_error_types() -> set[type]:
    """The exception classes defined in the modules of harness/ and fmu_src/ (found by
    importing each module, so that a new one cannot be left out of EXAMPLES)."""
    found = set()
    for package in (harness, fmu_src):
        for info in pkgutil.walk_packages(package.__path__, f"{package.__name__}."):
            if info.name.endswith("__main__") or info.name.split(".")[-1][0].isupper():
                continue  # the command's entry point; the slave scripts import pythonfmu
            module = importlib.import_module(info.name)
            found |= {value for value in vars(module).values() if isinstance(value, type)
                      and issubclass(value, BaseException) and value.__module__ == module.__name__}
    return found


def round_trip(error: BaseException) -> BaseException:
    """The error pickled and unpickled by the default protocol, as between a process pool's
    worker and its parent: without the reducers tblib registers in copyreg for every
    exception class once distributed is imported (as it is above)."""
    buffer = io.BytesIO()
    pickler = pickle.Pickler(buffer)
    pickler.dispatch_table = {}
    pickler.dump(error)
    return pickle.loads(buffer.getvalue())


def test_every_error_type_of_ours_has_an_example() -> None:
    assert defined_error_types() == set(EXAMPLES)


@pytest.mark.parametrize("kind", list(EXAMPLES), ids=lambda kind: kind.__name__)
def test_every_error_type_survives_pickling(kind: type) -> None:
    error = EXAMPLES[kind]
    copy = round_trip(error)
    assert type(copy) is kind and str(copy) == str(error) and vars(copy) == vars(error)


def test_fmu_call_error_keeps_the_fmus_words_through_pickling() -> None:
    copy = round_trip(fmu_call_error())
    assert str(copy) == ("SelfRegulatingBalancer: fmi2DoStep failed with status Error: "
                         "k = -5.0 N/m is outside")
    assert (copy.function, copy.status, copy.messages) == (
        "fmi2DoStep", FMI_ERROR, ["k = -5.0 N/m is outside"])


def test_an_fmu_error_in_a_cosim_worker_is_one_line(tmp_path: Path) -> None:
    """A payload of -1.4 kg from phase III on, two variants in two worker processes: the
    FMU's refusal when the master sets it, one line, exit 2 (it was BrokenProcessPool and a
    traceback)."""
    scenario = (ROOT / "harness/scenarios/franchetti2021.toml").read_text().replace(
        "payload = { ramp = 1.0 }", "payload = -1.4", 1)
    (tmp_path / "bad_payload.toml").write_text(scenario)
    done = subprocess.run(
        [sys.executable, "-m", "harness", "cosim", "--scenario",
         str(tmp_path / "bad_payload.toml"),
         "--variants", "self_regulating,unregulated", "--workers", "2", "--quiet",
         "--out", str(tmp_path / "out")],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    (line,) = done.stderr.splitlines()
    assert line.startswith("error: SelfRegulatingBalancer: fmi2SetReal failed")
    assert "input payload = -1.4 kg is outside [0.0, inf]" in line
    assert not list((tmp_path / "out").rglob("*.csv"))


# ---- CoSimFMU.close and a refused fmi2Terminate ---------------------------------------------
@pytest.fixture
def terminate_refused(srb_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The slave's terminate raises in instances made from now on (the slave class lives in
    this interpreter, imported by the FMU's runtime with the first instance)."""
    CoSimFMU(srb_fmu).close()

    def terminate(_slave: object) -> None:
        raise RuntimeError("could not flush the log")

    for module in bundled(SRB):
        monkeypatch.setattr(module.SelfRegulatingBalancer, "terminate", terminate)


def test_close_raises_a_refused_terminate_after_freeing(srb_fmu: Path,
                                                        terminate_refused: None) -> None:
    fmu = open_fmu(srb_fmu)
    unzipped = Path(fmu._unzip_dir)
    freed = []
    free_instance = fmu.slave.freeInstance
    fmu.slave.freeInstance = lambda: freed.append(free_instance())
    with pytest.raises(FMUCallError) as refused:
        fmu.close()
    assert str(refused.value) == ("SelfRegulatingBalancer: fmi2Terminate failed with status "
                                  "Error: fmi2Terminate: RuntimeError: could not flush the log")
    assert freed == [None] and not unzipped.exists()


def test_a_refused_terminate_does_not_hide_the_error_that_ended_the_block(
        srb_fmu: Path, terminate_refused: None) -> None:
    with pytest.raises(UserError) as raised:
        with open_fmu(srb_fmu):
            raise UserError("the run's own failure")
    assert str(raised.value) == "the run's own failure"
    assert raised.value.__notes__ == [
        "SelfRegulatingBalancer: fmi2Terminate failed with status Error: fmi2Terminate: "
        "RuntimeError: could not flush the log"]


def test_a_terminate_refused_at_the_end_of_a_block_is_raised(srb_fmu: Path,
                                                             terminate_refused: None) -> None:
    with pytest.raises(FMUCallError, match="fmi2Terminate failed"):
        with open_fmu(srb_fmu):
            pass
