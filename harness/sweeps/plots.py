"""The figures of a sweep's [plots] tables (docs/sweeps.md), drawn from its result table.

`saving` and `map` compare two variants of the sweep file on E_drawn (the plot's `variant`
and `baseline`); `lines` draws result columns per variant. Each figure is a
matplotlib.figure.Figure (no pyplot state), saved atomically beside the tables.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

from harness.io import save_figure
from harness.sweeps.definition import Sweep

# [%] the plots' floor: the saving tends to -inf where E_drawn(baseline) tends to 0
SAVING_FLOOR = -100.0


def saving(sweep: Sweep, table: pd.DataFrame, spec: dict[str, Any]) -> pd.DataFrame:
    """Per point of the result table: the axis values, E_drawn_<variant> [J] of the spec's
    variant and baseline, saving = 1 - E_drawn(variant) / E_drawn(baseline) (NaN where a run
    failed) and the spec's `mark` column."""
    axes = [a.name for a in sweep.axes]
    drawn = table[table.status == "ok"].pivot_table(index="point", columns="variant",
                                                    values="E_drawn")
    points = table.drop_duplicates("point").set_index("point")[axes]
    for variant in (spec["variant"], spec["baseline"]):
        points[f"E_drawn_{variant}"] = drawn[variant] if variant in drawn else np.nan
    points["saving"] = 1.0 - (points[f"E_drawn_{spec['variant']}"]
                              / points[f"E_drawn_{spec['baseline']}"])
    if spec.get("mark") in table:
        points[spec["mark"]] = table.groupby("point")[spec["mark"]].first()
    return points.reset_index(drop=True)


def _panels(sweep: Sweep, spec: dict[str, Any], data: pd.DataFrame, rows: int = 1
            ) -> tuple[Figure, list[tuple[Any, Sequence[Axes], pd.DataFrame]]]:
    """A figure with a column of `rows` panels per value of the spec's `panels` axis."""
    panel = spec.get("panels")
    groups = list(data.groupby(panel)) if panel else [(None, data)]
    fig = Figure(figsize=(5.2 * len(groups), 0.6 + 4.0 * rows), layout="constrained")
    axes = fig.subplots(rows, len(groups), squeeze=False, sharex=True, sharey="row")
    return fig, [(value, axes[:, i], group) for i, (value, group) in enumerate(groups)]


def _axis_label(sweep: Sweep, name: str) -> str:
    return next(a.label for a in sweep.axes if a.name == name)


def _panel_title(sweep: Sweep, spec: dict[str, Any], value: Any) -> str:
    return "" if value is None else f"{_axis_label(sweep, spec['panels'])} = {value:g}"


def saving_figure(sweep: Sweep, table: pd.DataFrame, spec: dict[str, Any]) -> Figure:
    """Against the x axis: the energy saving of `variant` against `baseline` [%] (top;
    values below SAVING_FLOOR drawn on it and labelled) and E_drawn of both [J] (bottom, log
    scale; variant solid, baseline dashed); one line per value of `lines`, one column per
    value of `panels`, a dotted line at the value of `mark`."""
    x, lines, mark = spec["x"], spec.get("lines"), spec.get("mark")
    variant, baseline = spec["variant"], spec["baseline"]
    points = saving(sweep, table, spec)
    fig, panels = _panels(sweep, spec, points, rows=2)
    for value, (top, bottom), group in panels:
        for i, (line, data) in enumerate(group.groupby(lines) if lines else [(None, group)]):
            data = data.sort_values(x)
            label = None if line is None else f"{_axis_label(sweep, lines)} = {line:g}"
            percent = 100.0 * data.saving
            top.plot(data[x], percent.clip(lower=SAVING_FLOOR), "o-", color=f"C{i}", ms=4,
                     lw=1.4, label=label)
            for at, below in zip(data[x][percent < SAVING_FLOOR],
                                 percent[percent < SAVING_FLOOR], strict=True):
                top.annotate(f"{below:.0f}", (at, SAVING_FLOOR), textcoords="offset points",
                             xytext=(5, 3 + 9 * i), fontsize=7, color=f"C{i}")
            bottom.semilogy(data[x], data[f"E_drawn_{variant}"], "o-", color=f"C{i}",
                            ms=4, lw=1.4)
            bottom.semilogy(data[x], data[f"E_drawn_{baseline}"], "s--",
                            color=f"C{i}", ms=4, lw=1.0, mfc="none")
        for ax in (top, bottom):
            if mark and mark in group and group[mark].notna().any():
                ax.axvline(float(group[mark].median()), color="k", ls=":", lw=1)
            ax.grid(alpha=0.3)
        if mark and mark in group and group[mark].notna().any():
            top.annotate(f"{mark} = {float(group[mark].median()):.3g} ",
                        (float(group[mark].median()), 0.5), ha="right",
                        xycoords=("data", "axes fraction"), fontsize=8)
        top.axhline(0.0, color="0.5", lw=0.8)
        top.set_ylim(SAVING_FLOOR - 8.0, 105.0)
        top.set_title(_panel_title(sweep, spec, value), fontsize=10)
        bottom.plot([], [], "ko-", ms=4, label=variant)
        bottom.plot([], [], "ks--", ms=4, mfc="none", label=baseline)
        bottom.legend(fontsize=8, loc="lower right")
        bottom.set_xlabel(_axis_label(sweep, x))
        if lines:
            top.legend(fontsize=8, loc="lower right")
    panels[0][1][0].set_ylabel(f"saving 1 - E_drawn({variant}) / E_drawn({baseline}) [%]")
    panels[0][1][1].set_ylabel("E_drawn [J]")
    fig.suptitle(f"{sweep.name}: drive energy saved by {variant} against {baseline} "
                 f"({sweep.scenario.name})")
    return fig


def map_figure(sweep: Sweep, table: pd.DataFrame, spec: dict[str, Any]) -> Figure:
    """Energy saving of `variant` against `baseline` [%] over two axes (a cell grid, or
    coloured points for a sample), one panel per value of `panels`; colours saturate below
    SAVING_FLOOR, numbers do not."""
    x, y = spec["x"], spec["y"]
    points = saving(sweep, table, spec)
    fig, panels = _panels(sweep, spec, points)
    norm = TwoSlopeNorm(vcenter=0.0, vmin=SAVING_FLOOR, vmax=100.0)
    for value, (ax,), group in panels:
        if sweep.sample == "grid":
            grid = 100.0 * group.pivot_table(index=y, columns=x, values="saving", dropna=False)
            image = ax.pcolormesh(np.arange(grid.shape[1] + 1), np.arange(grid.shape[0] + 1),
                                  grid.to_numpy(), cmap="RdYlGn", norm=norm)
            ax.set_xticks(np.arange(grid.shape[1]) + 0.5, [f"{v:g}" for v in grid.columns])
            ax.set_yticks(np.arange(grid.shape[0]) + 0.5, [f"{v:g}" for v in grid.index])
            for (row, col), cell in np.ndenumerate(grid.to_numpy()):
                if np.isfinite(cell):
                    ax.text(col + 0.5, row + 0.5, f"{cell:.0f}", ha="center", va="center",
                            fontsize=7)
        else:
            image = ax.scatter(group[x], group[y], c=100.0 * group.saving, cmap="RdYlGn",
                               norm=norm, s=30, edgecolors="k", linewidths=0.3)
        ax.set_title(_panel_title(sweep, spec, value), fontsize=10)
        ax.set_xlabel(_axis_label(sweep, x))
    panels[0][1][0].set_ylabel(_axis_label(sweep, y))
    fig.colorbar(image, ax=[axes[0] for _, axes, _ in panels], extend="min",
                 label="energy saving [%]")
    fig.suptitle(f"{sweep.name}: drive energy saved by {spec['variant']} against "
                 f"{spec['baseline']} [%]")
    return fig


def lines_figure(sweep: Sweep, table: pd.DataFrame, spec: dict[str, Any]) -> Figure:
    """One panel per `y` column (a row) and variant (a column) against the x axis, one line
    per value of `lines`; a variant without the column (all NaN) leaves its panel empty.
    `labels` may give a y column a longer label."""
    x, lines, labels = spec["x"], spec.get("lines"), spec.get("labels", {})
    ok = table[table.status == "ok"]
    variants = list(sweep.variants)
    fig = Figure(figsize=(5.2 * len(variants), 0.6 + 2.6 * len(spec["y"])), layout="constrained")
    axes = fig.subplots(len(spec["y"]), len(variants), squeeze=False, sharex=True)
    for row, column in enumerate(spec["y"]):
        for col, variant in enumerate(variants):
            ax = axes[row, col]
            data = ok[ok.variant == variant]
            if column in data and data[column].notna().any():
                groups = data.groupby(lines) if lines else [(None, data)]
                for i, (line, group) in enumerate(groups):
                    group = group.sort_values(x)
                    label = None if line is None else f"{_axis_label(sweep, lines)} = {line:g}"
                    ax.plot(group[x], group[column], "o-", color=f"C{i}", ms=3, lw=1.2,
                            label=label)
                if lines and row == 0:
                    ax.legend(fontsize=7)
            else:
                ax.text(0.5, 0.5, f"no {column}", transform=ax.transAxes, ha="center",
                        color="0.5")
            ax.grid(alpha=0.3)
            ax.set_ylabel(labels.get(column, column), fontsize=8)
            if row == 0:
                ax.set_title(variant, fontsize=10)
            if row == len(spec["y"]) - 1:
                ax.set_xlabel(_axis_label(sweep, x))
    fig.suptitle(f"{sweep.name}: {sweep.description or sweep.scenario.name}")
    return fig


# one per definition.PLOT_KINDS
FIGURES: dict[str, Callable[[Sweep, pd.DataFrame, dict[str, Any]], Figure]] = {
    "saving": saving_figure, "map": map_figure, "lines": lines_figure}


def plot(sweep: Sweep, table: pd.DataFrame, out: Path) -> list[Path]:
    """Draw the sweep's [plots] from its result table as <name>_<kind>.png in out."""
    return [save_figure(FIGURES[kind](sweep, table, spec), out / f"{sweep.name}_{kind}.png")
            for kind, spec in sweep.plots.items()]
