"""Every committed figure drawn again from the committed tables alone, without running a
co-simulation: a scenario's time series per loss set (its summary.csv and variant CSVs) and
its headline (the sets' summaries), a study's energy.png and dependence.png (runs.csv,
dependence.csv), a sweep's [plots] (its parquet table) and the bench's ecco.png (ecco.csv).

`committed` maps each PNG under the results folder to the function drawing it, which the
figure tests check; `redraw` writes the figures named (no command calls it: it rewrites
committed PNGs, never a table).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from functools import partial
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from harness import scenarios
from harness.bench.studies import ecco_figure
from harness.io import save_figure
from harness.run import plots as run_plots
from harness.run.results import RESULTS_DIR, StoredRun, energy_figure_path, read_summary
from harness.scenarios import losses
from harness.study import model as study_model
from harness.study import plots as study_plots
from harness.sweeps import definition
from harness.sweeps import plots as sweep_plots


def _time_series(scenario: scenarios.Scenario, folder: Path, loss_set: str) -> Figure:
    summary = read_summary(folder / "summary.csv")
    runs = [StoredRun(variant, model, pd.read_csv(folder / f"{variant}.csv"))
            for variant, model in zip(summary.variant, summary.model, strict=True)
            if (folder / f"{variant}.csv").exists()]
    return run_plots.figure(runs, scenario, loss_set)


def _headline(scenario: scenarios.Scenario, folders: dict[str, Path]) -> Figure:
    tables = {loss_set: table for loss_set, folder in folders.items()
              if (table := read_summary(folder / "summary.csv")) is not None}
    return run_plots.energy_figure(scenario, tables)


def _study(name: str, folder: Path, which: str) -> Figure | None:
    task_model = study_model.load(name)
    if which == "energy":
        runs = pd.read_csv(folder / "runs.csv")
        return study_plots.energy_figure(task_model.template.name, runs,
                                         list(task_model.template.variants),
                                         runs.task.nunique())
    return study_plots.dependence_figure(task_model.template.name,
                                         pd.read_csv(folder / "dependence.csv"),
                                         task_model.reference)


def _sweep(name: str, folder: Path, kind: str) -> Figure:
    sweep = definition.load(name)
    table = pd.read_parquet(folder / f"{name}.parquet")
    return sweep_plots.FIGURES[kind](sweep, table, sweep.plots[kind])


def committed(folder: Path = RESULTS_DIR) -> dict[Path, Callable[[], Figure | None]]:
    """Each figure the committed tables under folder give: its PNG -> the function drawing
    it (a study's dependence figure may be None, a study without task figures)."""
    figures: dict[Path, Callable[[], Figure | None]] = {}
    for name in scenarios.available():
        scenario = scenarios.load(name)
        folders = {loss_set: losses.result_folder(folder, scenario, loss_set)
                   for loss_set, _ in losses.loss_sets(scenario, "all")}
        folders = {s: f for s, f in folders.items() if (f / "summary.csv").exists()}
        played = dict(losses.loss_sets(scenario, "all"))
        for loss_set, set_folder in folders.items():
            figures[set_folder / f"{name}.png"] = partial(_time_series, played[loss_set],
                                                          set_folder, loss_set)
        if folders:
            figures[energy_figure_path(folders, scenario)] = partial(_headline, scenario, folders)
    for name in study_model.available():
        study = folder / "study" / name
        if (study / "runs.csv").exists():
            figures[study / "energy.png"] = partial(_study, name, study, "energy")
            figures[study / "dependence.png"] = partial(_study, name, study, "dependence")
    for path in sorted(definition.SWEEP_DIR.glob("*.toml")):
        sweeps = folder / "sweeps"
        if (sweeps / f"{path.stem}.parquet").exists():
            for kind in definition.load(path).plots:
                figures[sweeps / f"{path.stem}_{kind}.png"] = partial(_sweep, path.stem, sweeps,
                                                                      kind)
    ecco = folder / "bench" / "ecco.csv"
    if ecco.exists():
        figures[ecco.with_suffix(".png")] = lambda: ecco_figure(pd.read_csv(ecco))
    return figures


def redraw(paths: Iterable[Path], folder: Path = RESULTS_DIR) -> list[Path]:
    """Draw the named committed figures (paths among `committed(folder)`) from the tables
    and write them over their PNGs; the tables are only read."""
    paths, drawers = [Path(p) for p in paths], committed(folder)
    unknown = [str(p) for p in paths if p not in drawers]
    if unknown:
        raise KeyError(f"no committed figure: {', '.join(unknown)}")
    written = []
    for path in paths:
        fig = drawers[path]()
        if fig is not None:
            written.append(save_figure(fig, path))
    return written
