"""Ctrl-C (SIGINT): exit 130 with one line, whatever the worker count, and nothing lost.

An interrupt can land inside the slave's Python code (the FMU call then fails), inside the
FMI logger callback (where ctypes would print and drop it), or in a worker process while it
is idle or starting: each case must still end as one line and exit 130, never as an FMU error
(exit 2) or a traceback.
"""

from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pandas as pd
import pytest

from harness import interrupts
from harness.errors import UserError
from harness.run import cosim, results
from harness.run import scenario_files as scenarios
from tests.conftest import SRB, bundled

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def default_sigint() -> Iterator[None]:
    """Python's own SIGINT handler during each test, whatever the test process inherited (a
    shell starts a background job with SIGINT ignored), restored after."""
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, inherited)


# ---- the mechanism -------------------------------------------------------------------------
def test_a_sigint_inside_is_raised_on_leaving_in_place_of_the_error_it_caused() -> None:
    with pytest.raises(KeyboardInterrupt):
        with interrupts.deferred():
            signal.raise_signal(signal.SIGINT)  # only noted: the code goes on
            raise UserError("SelfRegulatingBalancer: fmi2DoStep failed: KeyboardInterrupt")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_without_a_sigint_errors_pass_unchanged() -> None:
    with pytest.raises(UserError, match="k = -5"):
        with interrupts.deferred():
            raise UserError("k = -5")


def test_an_ignored_sigint_stays_ignored(monkeypatch: pytest.MonkeyPatch) -> None:
    """E.g. a command started in the background by a non-interactive shell."""
    monkeypatch.setattr(signal, "getsignal", lambda _signal: signal.SIG_IGN)
    with interrupts.deferred():
        assert signal.signal(signal.SIGINT, signal.default_int_handler) is (
            signal.default_int_handler)  # deferred() left the handler alone


def test_processes_started_while_blocked_do_not_get_sigint() -> None:
    """The signal mask a child inherits (read from /proc), and the parent's afterwards."""
    with interrupts.blocked():
        child = subprocess.Popen(["sleep", "5"])
    try:
        status = Path(f"/proc/{child.pid}/status").read_text()
        (blocked,) = [int(line.split()[1], 16) for line in status.splitlines()
                      if line.startswith("SigBlk:")]
        assert blocked & 1 << (signal.SIGINT - 1)
        assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])
    finally:
        child.kill()
        child.wait()


@pytest.fixture
def slave_raising_sigint(srb_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """SelfRegulatingBalancer instances made from now on get a SIGINT inside their 200th
    do_step, in the slave's own Python code (as a Ctrl-C mostly lands: there the time goes)."""
    from harness.fmu.loader import CoSimFMU
    CoSimFMU(srb_fmu).close()  # the slave module imported into this interpreter
    calls = []
    for module in bundled(SRB):
        slave_class = module.SelfRegulatingBalancer

        def interrupted_step(self: object, *args: object,
                             do_step: Callable = slave_class.do_step) -> bool:
            calls.append(None)
            if len(calls) == 200:
                signal.raise_signal(signal.SIGINT)
            return do_step(self, *args)

        monkeypatch.setattr(slave_class, "do_step", interrupted_step)


def test_a_sigint_inside_the_fmu_is_the_interrupt_not_an_fmu_failure(
        slave_raising_sigint: None, tmp_path: Path) -> None:
    """It was FMUCallError 'fmi2DoStep failed with status Error' (before the runtime's
    change: Fatal, 'KeyboardInterrupt()')."""
    scenario = scenarios.load("franchetti2021")
    with pytest.raises(KeyboardInterrupt):
        cosim.run_all([(scenario, ["self_regulating"])], 1e-3, tmp_path, quiet=True)
    assert list(tmp_path.iterdir()) == []


# ---- Ctrl-C on the command at random times -------------------------------------------------
def interrupt_at_random(seed: int, command: list[str], earliest: float, latest: float
                        ) -> subprocess.CompletedProcess:
    """Run `python -m harness <command>` in its own process group with SIGINT's default
    action (a test runner may have it ignored), send SIGINT to the group, as a terminal's
    Ctrl-C does, after a delay drawn from [earliest, latest] s by the seed."""
    delay = random.Random(seed).uniform(earliest, latest)
    process = subprocess.Popen(
        [sys.executable, "-m", "harness", *command], cwd=ROOT, text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(delay)
    assert process.poll() is None, f"finished before the SIGINT at {delay:.2f} s"
    os.killpg(process.pid, signal.SIGINT)
    out, err = process.communicate(timeout=120)
    return subprocess.CompletedProcess(process.args, process.returncode, out, err)


def assert_interrupted(done: subprocess.CompletedProcess, line: str) -> None:
    """Exit 130 (or death by SIGINT, which a shell reports as 130: CPython ends so when the
    interrupt landed in code run by exec() of a string, e.g. a dataclass being made during
    the imports), and the one line."""
    assert done.returncode in (130, -signal.SIGINT), done.stderr
    assert done.stderr.splitlines() == [line], done.stderr


def hidden_files(folder: Path) -> list[Path]:
    """Temporary files and staging folders (their names start with a dot) left behind."""
    return [path for path in folder.rglob(".*")]


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize("seed", range(3))
def test_ctrl_c_on_cosim_exits_130_and_keeps_every_row(workers: int, seed: int,
                                                       tmp_path: Path) -> None:
    """Into a folder holding the committed franchetti2021 set: afterwards every variant of
    it is still there, with a series as long as the committed one (an old or a new run,
    never half a one)."""
    committed = results.RESULTS_DIR / "franchetti2021"
    shutil.copytree(committed, tmp_path / "franchetti2021")
    # at 0.5 ms the runs take about twice their 1 ms time (some 12 s on an idle 2-core
    # machine), so that the interrupt lands before the end however fast the machine; the
    # series are recorded at a fixed interval, so their length does not depend on the step
    done = interrupt_at_random(seed, ["cosim", "--scenario", "franchetti2021", "--variants",
                                      "all", "--workers", str(workers), "--quiet",
                                      "--step", "0.0005", "--out", str(tmp_path)], 0.5, 5.0)
    assert_interrupted(done, "interrupted")
    expected = pd.read_csv(committed / "summary.csv")
    kept = pd.read_csv(tmp_path / "franchetti2021" / "summary.csv")
    assert list(kept.variant) == list(expected.variant)
    for variant in expected.variant:
        assert len(pd.read_csv(tmp_path / "franchetti2021" / f"{variant}.csv")) == len(
            pd.read_csv(committed / f"{variant}.csv"))
    assert hidden_files(tmp_path) == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3))
def test_ctrl_c_on_a_sweep_exits_130_and_keeps_its_parts(seed: int, tmp_path: Path) -> None:
    done = interrupt_at_random(seed, ["sweep", "harness/sweeps/table1.toml", "--workers", "2",
                                      "--quiet", "--out", str(tmp_path)], 0.5, 12.0)
    # the last line (before it distributed may warn that another cluster has port 8787)
    assert "Traceback" not in done.stderr and done.stderr.splitlines()[-1] in (
        "interrupted",  # before the sweep started
        "interrupted: finished chunks are stored; run the same command to resume"), (
        done.stderr)
    assert done.returncode in (130, -signal.SIGINT)
    for part in (tmp_path / "table1").glob("part-*.parquet"):
        assert (pd.read_parquet(part).status == "ok").all()
    assert hidden_files(tmp_path) == []


