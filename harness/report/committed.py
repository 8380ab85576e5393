"""The committed result files the pages are made from (results/), each read once."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from harness.errors import UserError
from harness.report.prose import SCENARIO_FINDINGS
from harness.run.results import RESULTS_DIR
from harness.scenarios.losses import REALISTIC_FOLDER


def realistic(scenario: str) -> str:
    """The result set of the scenario's realistic loss set."""
    return f"{scenario}/{REALISTIC_FOLDER}"


@dataclass
class Results:
    """The committed result files under folder (results/), each read once."""

    folder: Path = RESULTS_DIR
    _tables: dict[str, pd.DataFrame] = field(default_factory=dict, repr=False)

    def csv(self, name: str) -> pd.DataFrame:
        """results/<name>.csv; UserError naming it when it is missing."""
        if name not in self._tables:
            path = self.folder / f"{name}.csv"
            if not path.is_file():
                raise UserError(f"{path} is missing: run `make cosim`, `make sweep` or "
                                "`make bench` first")
            self._tables[name] = pd.read_csv(path)
        return self._tables[name]

    def summary(self, result_set: str) -> pd.DataFrame:
        """results/<result_set>/summary.csv by variant."""
        return self.csv(f"{result_set}/summary").set_index("variant", drop=False)

    def at(self, result_set: str, variant: str, time: float) -> pd.Series:
        """The recorded row of results/<result_set>/<variant>.csv nearest to time [s]."""
        series = self.csv(f"{result_set}/{variant}")
        return series.iloc[int(np.abs(series.time - time).argmin())]

    def scenarios(self) -> list[str]:
        """The scenarios with a result set, in the order of their findings files (others
        follow by name)."""
        return SCENARIO_FINDINGS.in_order(p.parent.name for p in self.folder.glob("*/summary.csv"))

    def studies(self) -> list[str]:
        """The scenarios with a committed study (results/study/<scenario>/summary.csv), in
        the order of their findings files."""
        return SCENARIO_FINDINGS.in_order(
            p.parent.name for p in self.folder.glob("study/*/summary.csv"))

    def has_realistic(self, scenario: str) -> bool:
        return (self.folder / scenario / REALISTIC_FOLDER / "summary.csv").is_file()
