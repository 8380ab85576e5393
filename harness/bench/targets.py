"""The bench's checks of its tables against the targets, and the tables a run keeps from an
earlier one."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness.bench.steps import FLOOR_MODELS
from harness.bench.studies import HELP_SECONDS_BOUND
from harness.errors import UserError
from harness.study import model as study_model


@dataclass(frozen=True)
class Check:
    """A benchmark figure that must lie on one side of a bound (a NaN figure fails)."""

    benchmark: str
    figure: str
    value: float
    relation: str  # "<" or ">": value relation bound must hold
    bound: float
    unit: str

    @property
    def passed(self) -> bool:
        return self.value < self.bound if self.relation == "<" else self.value > self.bound


def fmu_step_checks(table: pd.DataFrame) -> Iterator[Check]:
    """Every mechanism's step costs more than the stock floor's: ratio_to_floor > 1."""
    for row in table[~table.model.isin(FLOOR_MODELS)].itertuples():
        yield Check("fmu_step", f"{row.model} ratio_to_floor", row.ratio_to_floor, ">", 1.0, "")


def cli_help_checks(table: pd.DataFrame) -> Iterator[Check]:
    """The top-level help, best of repeats, takes under HELP_SECONDS_BOUND."""
    for row in table.itertuples():
        yield Check("cli_help", f"{row.command} best_s", row.best_s, "<", HELP_SECONDS_BOUND,
                    "s")


# the largest error a study's step may leave in a run's E_drawn against the finest step: the
# level the convergence study states for the headline tables' 1 ms (results/bench/
# convergence.csv: 4.2e-4 to 3.5e-3 against the monolithic reference)
STUDY_STEP_BOUND = 1e-3


def study_step_checks(table: pd.DataFrame) -> Iterator[Check]:
    """At each task model's step, every run's E_drawn lies within STUDY_STEP_BOUND of its
    value at the finest step (relative)."""
    for name, rows in table.groupby("scenario"):
        step = study_model.load(name).step
        at_step = rows[rows.step_size == step]
        yield Check("study_step", f"{name} rel_error at {1e3 * step:g} ms",
                    at_step.rel_error.max(), "<", STUDY_STEP_BOUND, "")


CHECKS: dict[str, Callable[[pd.DataFrame], Iterator[Check]]] = {
    "fmu_step": fmu_step_checks,
    "cli_help": cli_help_checks,
    "study_step": study_step_checks,
}


def checks(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """The checks of the given benchmark tables (name -> table), in CHECKS' order: benchmark,
    figure, value, relation, bound, unit, passed."""
    rows = [{**vars(check), "passed": check.passed}
            for name, check_table in CHECKS.items() if name in tables
            for check in check_table(tables[name])]
    return pd.DataFrame(rows, columns=["benchmark", "figure", "value", "relation", "bound",
                                       "unit", "passed"])


def earlier_tables(folder: Path, skip: Sequence[str]) -> dict[str, pd.DataFrame]:
    """The checked benchmarks' tables already in folder, but those in skip; UserError naming
    a file that is not such a table."""
    tables = {}
    for name in CHECKS:
        path = folder / f"{name}.csv"
        if name in skip or not path.is_file():
            continue
        try:
            tables[name] = pd.read_csv(path)
            checks({name: tables[name]})
        except (OSError, UnicodeDecodeError, ValueError, AttributeError, KeyError) as error:
            raise UserError(f"{path}: not a {name} table ({error}); rerun --only {name} or "
                            "remove it") from None
    return tables
