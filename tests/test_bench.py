"""The bench's checks (harness.bench.targets.CHECKS) on fabricated tables: which figures are checked
against which bound, what checks.csv holds and the exit status; no timing."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from harness import bench, cli
from harness.bench.targets import checks


def fmu_step_table(mechanism_ratio: float) -> pd.DataFrame:
    """An fmu_step table: the two floors (the runtime's far below the stock one, which is not
    checked) and two mechanisms, one of them at mechanism_ratio."""
    ratios = [1.0, 0.75, 1.7, mechanism_ratio]
    return pd.DataFrame({"model": ["BenchFloor", "BenchFloorRuntime", "CiupituBalancer",
                                   "SelfRegulatingBalancer"],
                         "us_per_step": [10.0 * r for r in ratios], "ratio_to_floor": ratios})


def master_share_table(fmu_calls_us: float) -> pd.DataFrame:
    return pd.DataFrame({"scenario": "demian2022", "variant": ["compensated", "uncompensated"],
                         "us_per_step": [20.0, 30.0], "fmu_calls_us_per_step": [15.0,
                                                                                 fmu_calls_us]})


def help_table(best_s: float) -> pd.DataFrame:
    return pd.DataFrame({"command": ["python -m harness --help"], "repeats": 3,
                         "best_s": [best_s], "worst_s": [best_s + 0.5]})


def verdicts(table: pd.DataFrame) -> dict[str, bool]:
    return dict(zip(table.figure, table.passed))


@pytest.mark.parametrize(("ratio", "passed"), [(1.2, True), (1.0, False), (0.98, False),
                                               (math.nan, False)])
def test_every_mechanism_step_must_cost_more_than_the_floor(ratio: float, passed: bool) -> None:
    table = checks({"fmu_step": fmu_step_table(ratio)})
    assert verdicts(table) == {"CiupituBalancer ratio_to_floor": True,
                               "SelfRegulatingBalancer ratio_to_floor": passed}
    row = table.iloc[1]
    assert (row.relation, row.bound) == (">", 1.0)
    assert row.value == ratio or math.isnan(ratio)


@pytest.mark.parametrize(("best_s", "passed"), [(0.4, True), (1.0, False), (1.3, False)])
def test_the_top_level_help_must_take_under_a_second(best_s: float, passed: bool) -> None:
    table = checks({"cli_help": help_table(best_s)})
    assert verdicts(table) == {"python -m harness --help best_s": passed}
    assert (table.bound.iloc[0], table.unit.iloc[0]) == (1.0, "s")


def study_step_table(error_at_study_step: float) -> pd.DataFrame:
    """A study_step table for franchetti2021 (whose task model steps at 2 ms): its error at
    2 ms is error_at_study_step, at 4 ms far above any bound, at 0.5 ms 0 (the finest)."""
    return pd.DataFrame({"scenario": "franchetti2021", "task": 0, "variant": "ciupitu",
                         "losses": "realistic", "step_size": [0.004, 0.002, 0.0005],
                         "E_drawn": 1.0, "rel_error": [0.05, error_at_study_step, 0.0]})


@pytest.mark.parametrize(("error", "passed"), [(4e-4, True), (1e-3, False), (2.1e-2, False)])
def test_a_study_step_must_leave_under_1e_3_of_e_drawn(error: float, passed: bool) -> None:
    """Only the task model's own step is checked (4 ms's error is not the study's)."""
    table = checks({"study_step": study_step_table(error)})
    assert verdicts(table) == {"franchetti2021 rel_error at 2 ms": passed}
    assert table.value.iloc[0] == error and table.bound.iloc[0] == 1e-3


def test_unchecked_benchmarks_give_no_checks() -> None:
    """The convergence table, and the master's share of a step, are reported figures: the
    latter compares two timings taken seconds apart, which the machine's load moves more than
    any bound a check could hold."""
    assert checks({"convergence": pd.DataFrame({"x": [1.0]}),
                         "master_share": master_share_table(33.0)}).empty


def fabricate(monkeypatch: pytest.MonkeyPatch, **tables: pd.DataFrame) -> None:
    for name, table in tables.items():
        monkeypatch.setitem(bench.BENCHMARKS, name, lambda steps, repeats, t=table: t)


def test_bench_writes_the_checks_and_fails_on_one(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture) -> None:
    """A failing check: every table is still written, checks.csv holds each figure, its bound
    and the verdict, the failure is one line on stderr, and the exit status is 1."""
    fabricate(monkeypatch, fmu_step=fmu_step_table(0.98), master_share=master_share_table(25.0),
              cli_help=help_table(0.3))
    assert cli.main(["bench", "--only", "fmu_step,master_share,cli_help",
                     "--out", str(tmp_path)]) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "checks.csv", "cli_help.csv", "fmu_step.csv", "master_share.csv"]
    written = pd.read_csv(tmp_path / "checks.csv")
    assert list(written.columns) == ["benchmark", "figure", "value", "relation", "bound",
                                     "unit", "passed"]
    assert list(written.benchmark) == ["fmu_step"] * 2 + ["cli_help"]
    assert list(written.passed) == [True, False, True]
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["bench check failed: fmu_step: SelfRegulatingBalancer ratio_to_floor = "
                   "0.98, must be > 1"]


def test_bench_keeps_the_checks_of_tables_it_did_not_rerun(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`--only fmu_step` over a folder holding a failing cli_help.csv: checks.csv keeps
    that table's check (re-evaluated from the CSV, failing), the exit status covers only the
    benchmark run now (0); an earlier table that is not one is refused in one line."""
    help_table(1.3).to_csv(tmp_path / "cli_help.csv", index=False)
    fabricate(monkeypatch, fmu_step=fmu_step_table(1.5))
    assert cli.main(["bench", "--only", "fmu_step", "--out", str(tmp_path)]) == 0
    written = pd.read_csv(tmp_path / "checks.csv")
    assert list(zip(written.benchmark, written.passed)) == [
        ("fmu_step", True), ("fmu_step", True), ("cli_help", False)]
    (tmp_path / "cli_help.csv").write_text("variant\nx\n")
    assert cli.main(["bench", "--only", "fmu_step", "--out", str(tmp_path)]) == 2
