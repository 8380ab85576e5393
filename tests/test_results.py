"""Result sets (harness.run.results.write_run): no row is dropped whatever the layouts, staging
folders left by killed writers are removed and live ones kept, concurrent writers keep every
row, a corrupt summary is refused before simulating, a full disk leaves the set as it was."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import multiprocessing
import multiprocessing.synchronize
import os
import shutil
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from harness import cli, scenarios
from harness.engines.result import RunResult
from harness.errors import UserError
from harness.run import cosim, results
from harness.run.results import RESULTS_DIR, STAGING_PREFIX

VARIANTS = [f"v{index}" for index in range(12)]
SCENARIO = '''
name = "many"
model = "SelfRegulatingBalancer"
initial_angle_deg = 60.0
baseline = "v0"
[parameters]
[[phases]]
name = "hold"
duration = 0.2
target_deg = 60.0
''' + "".join(f"[variants.{name}]\n" for name in VARIANTS)


@pytest.fixture
def scenario(tmp_path: Path) -> scenarios.Scenario:
    path = tmp_path / "many.toml"
    path.write_text(SCENARIO)
    return scenarios.load(str(path))


def made_up_run(scenario: scenarios.Scenario, variant: str, energy: float) -> RunResult:
    """A one-joint run with E_drawn = energy [J] (no simulation: write_run needs only this)."""
    times = np.linspace(0.0, scenario.duration, 5)
    return RunResult(scenario.name, variant, "SelfRegulatingBalancer", 1e-3,
                     pd.DataFrame({"time": times, "theta": np.full(5, 1.0),
                                   **dict.fromkeys(("tau_drive", "i", "P_elec", "E_drawn"),
                                                   np.linspace(0.0, energy, 5))}),
                     {"E_in": energy, "E_drawn": energy}, {}, {},
                     {scenario.joints[0].name: {"hold": energy / 2}})


@contextlib.contextmanager
def held(folder: Path) -> Iterator[None]:
    """Hold folder's flock as a live writer does while it stages."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


# ---- every row kept

@pytest.mark.slow
def test_one_variant_into_the_committed_set_keeps_every_row(tmp_path: Path) -> None:
    """cosim --variants unbalanced into a copy of results/franchetti2021 kept 1 of its
    rows (then 5) (the one-joint run's columns differ from the set's per-joint ones). Now the set is
    as committed: same rows, columns and numbers (eps recomputed from the stored 10-digit
    E_drawn of the other rows), the other variants' CSVs untouched."""
    committed = RESULTS_DIR / "franchetti2021"
    shutil.copytree(committed, tmp_path / "franchetti2021")
    assert cli.main(["cosim", "--scenario", "franchetti2021", "--variants", "unbalanced",
                     "--out", str(tmp_path), "--quiet"]) == 0
    expected = pd.read_csv(committed / "summary.csv")
    merged = pd.read_csv(tmp_path / "franchetti2021" / "summary.csv")
    assert list(expected.variant) == list(scenarios.load("franchetti2021").variants)
    pd.testing.assert_frame_equal(merged, expected, rtol=1e-9)
    for other in set(expected.variant) - {"unbalanced"}:
        assert ((tmp_path / "franchetti2021" / f"{other}.csv").read_bytes()
                == (committed / f"{other}.csv").read_bytes()), other


def test_rows_of_another_layout_are_merged_by_the_union_of_the_columns(
        tmp_path: Path, scenario: scenarios.Scenario) -> None:
    """An old summary with a column the new runs lack, a variant the scenario no longer has
    and a row whose CSV is gone: every row is kept, the new run adds its row."""
    out = tmp_path / "set"
    out.mkdir()
    pd.DataFrame({"variant": ["v0", "retired", "v2"], "E_drawn": [2.0, 3.0, 4.0],
                  "old_metric": [7.0, 8.0, 9.0], "model": "SelfRegulatingBalancer",
                  "step_size": 1e-3}).to_csv(out / "summary.csv", index=False)
    for variant in ("v0", "retired"):  # v2's CSV is missing
        made_up_run(scenario, variant, 1.0).series.to_csv(out / f"{variant}.csv", index=False)
    results.write_run([made_up_run(scenario, "v1", 1.0)], scenario, out)
    table = pd.read_csv(out / "summary.csv")
    assert list(table.variant) == ["v0", "v1", "v2", "retired"]  # scenario order, then others
    assert table.old_metric.tolist()[:1] + table.old_metric.tolist()[2:] == [7.0, 9.0, 8.0]
    assert np.isnan(table.old_metric[1]) and table.E_in[1] == 1.0 and np.isnan(table.E_in[0])
    # eps against v0's stored E_drawn (1 - 1/2), recomputed for every row
    assert table.eps.tolist()[:3] == pytest.approx([0.0, 0.5, -1.0])
    assert table.columns[0] == "variant" and "old_metric" in table.columns


# ---- staging folders

def test_a_stale_staging_folder_is_removed_and_a_live_one_kept(
        tmp_path: Path, scenario: scenarios.Scenario) -> None:
    """A writer SIGKILLed while staging left its .staging.* folder forever (6 after 12
    kills). The next write removes every one no live process holds."""
    out = tmp_path / "set"
    stale, live = out / f"{STAGING_PREFIX}killed", out / f"{STAGING_PREFIX}live"
    for folder in (stale, live):
        folder.mkdir(parents=True)
        (folder / "summary.csv").write_text("half")
    with held(live):
        results.write_run([made_up_run(scenario, "v0", 1.0)], scenario, out)
        assert not stale.exists() and (live / "summary.csv").read_text() == "half"
    assert sorted(p.name for p in out.iterdir()) == [f"{STAGING_PREFIX}live", "many.png",
                                                     "summary.csv", "v0.csv"]


def _stage_and_wait(out: Path, staged: multiprocessing.synchronize.Event) -> None:
    with results.locked(out), results.staging(out) as folder:
        (folder / "summary.csv").write_text("half")
        staged.set()
        time.sleep(60)


def test_a_writer_sigkilled_while_staging_leaves_a_folder_the_next_write_removes(
        tmp_path: Path, scenario: scenarios.Scenario) -> None:
    out = tmp_path / "set"
    context = multiprocessing.get_context("fork")
    staged = context.Event()
    writer = context.Process(target=_stage_and_wait, args=(out, staged))
    writer.start()
    assert staged.wait(30)
    os.kill(writer.pid, signal.SIGKILL)
    writer.join(30)
    assert len(list(out.glob(f"{STAGING_PREFIX}*"))) == 1
    results.write_run([made_up_run(scenario, "v0", 1.0)], scenario, out)
    assert not list(out.glob(f"{STAGING_PREFIX}*"))


def _write_one(scenario: scenarios.Scenario, variant: str, out: Path) -> None:
    results.write_run([made_up_run(scenario, variant, 1.0 + VARIANTS.index(variant))],
                      scenario, out)


@pytest.mark.slow
def test_twelve_concurrent_writers_keep_every_row(tmp_path: Path,
                                                  scenario: scenarios.Scenario) -> None:
    """12 processes writing one variant each into one folder (with a stale staging folder in
    it): every row is there and no staging folder is left."""
    out = tmp_path / "set"
    (out / f"{STAGING_PREFIX}killed").mkdir(parents=True)
    context = multiprocessing.get_context("fork")
    writers = [context.Process(target=_write_one, args=(scenario, variant, out))
               for variant in VARIANTS]
    for writer in writers:
        writer.start()
    for writer in writers:
        writer.join(60)
        assert writer.exitcode == 0
    table = pd.read_csv(out / "summary.csv")
    assert list(table.variant) == VARIANTS
    assert table.E_drawn.tolist() == [1.0 + index for index in range(12)]
    assert not list(out.glob(f"{STAGING_PREFIX}*"))


# ---- a corrupt summary, a full disk

@pytest.mark.parametrize(("content", "named"), [
    (b"", "cannot be read as a CSV table (No columns to parse from file)"),
    (b"\xff\xfe\x00garbage\n", "cannot be read as a CSV table"),
    (b'"a","b"\n1,2\n', "no variant column"),
    (b'"variant","model"\nv0,M\nv0,M\n', "lists variant(s) v0 twice"),
], ids=["empty", "not-utf8", "no-variant", "repeated"])
def test_a_corrupt_summary_is_refused_before_simulating(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        content: bytes, named: str) -> None:
    """It was found only after the runs, as a traceback."""
    path = tmp_path / "many.toml"
    path.write_text(SCENARIO)
    summary = tmp_path / "out" / "many" / "summary.csv"
    summary.parent.mkdir(parents=True)
    summary.write_bytes(content)

    def simulated(*_args: object) -> None:
        raise AssertionError("simulated before checking the summary")

    monkeypatch.setattr(cosim, "run_all", simulated)
    assert cli.main(["cosim", "--scenario", str(path), "--variants", "v0", "--out",
                     str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith(f"error: {summary} ") and named in err
    assert summary.read_bytes() == content


def test_a_full_disk_is_one_line_and_leaves_the_set_as_it_was(
        tmp_path: Path, scenario: scenarios.Scenario, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "set"
    results.write_run([made_up_run(scenario, "v0", 1.0)], scenario, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def disk_full(*_args: object, **_kwargs: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(pd.DataFrame, "to_csv", disk_full)
    with pytest.raises(results.UserError) as refused:
        results.write_run([made_up_run(scenario, "v1", 2.0)], scenario, out)
    message = str(refused.value)
    assert "\n" not in message and "v1.csv: No space left on device" in message
    assert f"the result set in {out} is as it was" in message
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


# ---- no run mixes its rows into a set made otherwise

FMPY_SIZED = {"engine": "fmpy", "drives": "sized", "step": 1e-3}


@pytest.mark.parametrize(("option", "value", "named"), [
    ("--step", "0.002", "step 0.001, not 0.002"),
    ("--drives", "legacy", "drives 'sized', not 'legacy'"),
    ("--engine", "reference", "engine 'fmpy', not 'reference'")])
def test_cosim_refuses_a_committed_set_made_with_other_settings(
        option: str, value: str, named: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Into results/ (the default folder of the FMPy master, given by --out for the others),
    a run at another step, with other drives or another engine is refused before anything
    runs, in one line that names the setting and the options that write anyway; nothing is
    written."""
    before = {p: p.stat().st_mtime_ns for p in (RESULTS_DIR / "franchetti2021").rglob("*")}
    assert cli.main(["cosim", "--scenario", "franchetti2021", "--variants", "unbalanced",
                     option, value, "--out", str(RESULTS_DIR), "--quiet"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and named in error and "--out" in error \
        and "--replace" in error
    assert {p: p.stat().st_mtime_ns for p in (RESULTS_DIR / "franchetti2021").rglob("*")} \
        == before


def test_every_committed_set_records_how_it_was_made() -> None:
    """The committed sets are the FMPy master's with the sized drives at 1 ms, as
    `make cosim` makes them (and records them)."""
    files = sorted(RESULTS_DIR.glob(f"*/**/{results.SETTINGS}"))
    folders = {p.parent for p in RESULTS_DIR.glob("*/**/summary.csv")
               if "study" not in p.parts and "sweeps" not in p.parts}
    assert {p.parent for p in files if "study" not in p.parts} == folders and len(folders) == 6
    for path in files:
        if "study" not in path.parts:
            assert json.loads(path.read_text()) == FMPY_SIZED, path


def test_replace_starts_the_set_anew(tmp_path: Path, scenario: scenarios.Scenario) -> None:
    """A set refused for its settings is written with replace: its summary holds the new
    rows alone, the other variants' CSVs are gone, the settings file is the new one."""
    out = tmp_path / "set"
    results.write_run([made_up_run(scenario, "v0", 1.0), made_up_run(scenario, "v1", 2.0)],
                      scenario, out, settings=FMPY_SIZED)
    other = FMPY_SIZED | {"step": 2e-3}
    with pytest.raises(UserError, match="step 0.001, not 0.002"):
        results.check_result_set(out, other)
    results.check_result_set(out, other, replace=True)
    results.write_run([made_up_run(scenario, "v0", 3.0)], scenario, out, settings=other,
                      replace=True)
    assert list(pd.read_csv(out / "summary.csv").variant) == ["v0"]
    assert not (out / "v1.csv").exists()
    assert json.loads((out / results.SETTINGS).read_text()) == other
    results.check_result_set(out, other)


def test_the_printed_summary_fits_a_terminal() -> None:
    """Every committed set's printed summary: the variant, E_drawn, eps and the drive, each
    row within 100 characters, every variant once with its E_drawn as the CSV has it."""
    for path in sorted(RESULTS_DIR.glob("*/summary.csv")) + sorted(
            RESULTS_DIR.glob("*/realistic/summary.csv")):
        name = path.relative_to(RESULTS_DIR).parts[0]
        loss_set = "realistic" if path.parent.name == "realistic" else "ideal"
        text = results.summary_text(path, scenarios.load(name), loss_set)
        lines = text.splitlines()
        assert max(map(len, lines)) <= results.WIDTH, path
        assert lines[1].split() == ["variant", "E_drawn", "[J]", "eps", "drive"]
        table = pd.read_csv(path)
        for row, line in zip(table.itertuples(), lines[2:], strict=False):
            variant, drawn, eps, *_ = line.split()
            assert (variant, float(drawn)) == (row.variant, pytest.approx(row.E_drawn,
                                                                          rel=5e-4))
