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
from matplotlib.lines import Line2D

from harness.io import save_figure
from harness.run.plots import fit_suptitle, readable_log, show_coinciding, significant
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
    fig = Figure(figsize=(max(5.2 * len(groups), 6.4) + 0.8, 1.6 + 3.8 * rows),
                 layout="constrained")
    axes = fig.subplots(rows, len(groups), squeeze=False, sharex=True, sharey="row")
    return fig, [(value, axes[:, i], group) for i, (value, group) in enumerate(groups)]


def _axis_label(sweep: Sweep, name: str) -> str:
    """An axis's label on a figure's axis: its name and unit, [-] for a number without one."""
    axis = next(a for a in sweep.axes if a.name == name)
    return axis.label if axis.unit else f"{axis.name} [-]"


def _value_label(sweep: Sweep, spec: dict[str, Any], role: str, value: Any) -> str:
    """What a value of the spec's `role` axis (lines, panels) is called: the spec's
    `<role>_labels` name for it (a table of the value as written, '0', '0.05'), else
    '<axis label> = <value>'."""
    named = spec.get(f"{role}_labels", {}).get(f"{value:g}")
    return named or f"{next(a.label for a in sweep.axes if a.name == spec[role])} = {value:g}"


def _legend(fig: Figure, handles: list[Line2D]) -> None:
    """The figure's legend, under its panels (no legend covers data)."""
    if handles:
        fig.legend(handles=handles, loc="outside lower center", fontsize=8,
                   ncols=min(len(handles), 4))


def saving_figure(sweep: Sweep, table: pd.DataFrame, spec: dict[str, Any]) -> Figure:
    """Against the x axis: the energy saving of `variant` against `baseline` [%] (top;
    values below SAVING_FLOOR drawn on it and labelled) and E_drawn of both [J] (bottom, log
    scale; variant solid, baseline dashed); one line per value of `lines`, one column per
    value of `panels`, a dotted line at the value of `mark`; the legend under the panels."""
    x, lines, mark = spec["x"], spec.get("lines"), spec.get("mark")
    variant, baseline = spec["variant"], spec["baseline"]
    points = saving(sweep, table, spec)
    fig, panels = _panels(sweep, spec, points, rows=2)
    handles: dict[str, Line2D] = {}
    drawn: dict[Axes, list[Line2D]] = {}
    for value, (top, bottom), group in panels:
        for i, (line, data) in enumerate(group.groupby(lines) if lines else [(None, group)]):
            data = data.sort_values(x)
            percent = 100.0 * data.saving
            label = None if line is None else _value_label(sweep, spec, "lines", line)
            drawn.setdefault(top, []).extend(top.plot(
                data[x], percent.clip(lower=SAVING_FLOOR), "o-", color=f"C{i}", ms=4, lw=1.4,
                label=label))
            if label is not None:
                handles.setdefault(label, Line2D([], [], color=f"C{i}", lw=1.4, label=label))
            for at, below in zip(data[x][percent < SAVING_FLOOR],
                                 percent[percent < SAVING_FLOOR], strict=True):
                top.annotate(f"{below:.0f}", (at, SAVING_FLOOR), textcoords="offset points",
                             xytext=(5, 3 + 9 * i), fontsize=7, color=f"C{i}")
            drawn.setdefault(bottom, []).extend([
                *bottom.semilogy(data[x], data[f"E_drawn_{variant}"], "o-", color=f"C{i}",
                                 ms=4, lw=1.4),
                *bottom.semilogy(data[x], data[f"E_drawn_{baseline}"], "s--", color=f"C{i}",
                                 ms=4, lw=1.0, mfc="none")])
        title = "" if value is None else _value_label(sweep, spec, "panels", value)
        if mark and mark in group and group[mark].notna().any():
            at = float(group[mark].median())
            for ax in (top, bottom):
                ax.axvline(at, color="k", ls=":", lw=1)
            title = "; ".join(t for t in (title, f"dotted: {mark} = {significant(at)}") if t)
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
        top.axhline(0.0, color="0.5", lw=0.8)
        top.set_title(title, fontsize=10)
        readable_log(bottom.yaxis)
        bottom.set_xlabel(_axis_label(sweep, x))
    shown = 100.0 * points.saving.clip(lower=SAVING_FLOOR / 100.0)
    if shown.notna().any():
        low, high = float(shown.min()), float(shown.max())
        pad = max(5.0, 0.08 * (high - low))
        panels[0][1][0].set_ylim(low - pad, min(high + pad, 101.0))  # no saving above 100 %
    for lines_drawn in drawn.values():  # the limits set
        show_coinciding(lines_drawn)
    panels[0][1][0].set_ylabel("energy saving [%]")
    panels[0][1][1].set_ylabel("E_drawn [J]")
    _legend(fig, [*handles.values(),
                  Line2D([], [], color="k", marker="o", ms=4, label=f"E_drawn of {variant}"),
                  Line2D([], [], color="k", marker="s", ms=4, mfc="none", ls="--",
                         label=f"E_drawn of {baseline}")])
    fit_suptitle(fig, f"{sweep.name}: drive energy saved by {variant} against {baseline} "
                      f"({sweep.scenario.name}), saving = 1 - E_drawn({variant}) / "
                      f"E_drawn({baseline})")
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
        ax.set_title("" if value is None else _value_label(sweep, spec, "panels", value),
                     fontsize=10)
        ax.set_xlabel(_axis_label(sweep, x))
    panels[0][1][0].set_ylabel(_axis_label(sweep, y))
    fig.colorbar(image, ax=[axes[0] for _, axes, _ in panels], extend="min",
                 label="energy saving [%]")
    fit_suptitle(fig, f"{sweep.name}: drive energy saved by {spec['variant']} against "
                      f"{spec['baseline']} ({sweep.scenario.name}), saving = 1 - "
                      f"E_drawn({spec['variant']}) / E_drawn({spec['baseline']})")
    return fig


def lines_layout(columns: Sequence[str], has: dict[str, list[str]]
                 ) -> tuple[int, dict[tuple[str, str], int]]:
    """The rows of a lines figure and the row of each (variant, column) drawn: the columns
    every variant has share the bottom rows, in order; above them each variant's own columns,
    in order, down to the shared ones (no panel for a column a variant lacks)."""
    shared = [c for c in columns if all(c in mine for mine in has.values())]
    own = {v: [c for c in mine if c not in shared] for v, mine in has.items()}
    above = max((len(mine) for mine in own.values()), default=0)
    rows = {(v, c): above - len(mine) + k for v, mine in own.items()
            for k, c in enumerate(mine)}
    rows |= {(v, c): above + k for v in has for k, c in enumerate(shared)}
    return above + len(shared), rows


def lines_figure(sweep: Sweep, table: pd.DataFrame, spec: dict[str, Any]) -> Figure:
    """One panel per `y` column and variant that has it (not all NaN) against the x axis, a
    column of panels per variant (`lines_layout`), one line per value of `lines` (the legend
    under the panels). `labels` may give a y column a longer label."""
    x, lines, labels = spec["x"], spec.get("lines"), spec.get("labels", {})
    ok = table[table.status == "ok"]
    variants = list(sweep.variants)
    has = {v: [c for c in spec["y"] if c in ok and ok[ok.variant == v][c].notna().any()]
           for v in variants}
    rows, row_of = lines_layout(spec["y"], has)
    fig = Figure(figsize=(5.2 * len(variants), 1.2 + 2.6 * max(rows, 1)), layout="constrained")
    axes = fig.subplots(max(rows, 1), len(variants), squeeze=False, sharex=True)
    handles: dict[str, Line2D] = {}
    for col, variant in enumerate(variants):
        data = ok[ok.variant == variant]
        for ax in axes[:, col]:
            ax.set_visible(False)
        for column in has[variant]:
            ax = axes[row_of[(variant, column)], col]
            ax.set_visible(True)
            drawn = []
            for i, (line, group) in enumerate(data.groupby(lines) if lines else [(None, data)]):
                group = group.sort_values(x)
                label = None if line is None else _value_label(sweep, spec, "lines", line)
                drawn += ax.plot(group[x], group[column], "o-", color=f"C{i}", ms=3, lw=1.2,
                                 label=label)
                if label is not None:
                    handles.setdefault(label, Line2D([], [], color=f"C{i}", marker="o", ms=3,
                                                     label=label))
            show_coinciding(drawn)
            ax.grid(alpha=0.3)
            ax.set_ylabel(labels.get(column, column), fontsize=8)
        if has[variant]:
            axes[row_of[(variant, has[variant][0])], col].set_title(variant, fontsize=10)
        axes[-1, col].set_xlabel(_axis_label(sweep, x))
    _legend(fig, list(handles.values()))
    fit_suptitle(fig, f"{sweep.name}: {sweep.description or sweep.scenario.name}")
    return fig


# one per definition.PLOT_KINDS
FIGURES: dict[str, Callable[[Sweep, pd.DataFrame, dict[str, Any]], Figure]] = {
    "saving": saving_figure, "map": map_figure, "lines": lines_figure}


def plot(sweep: Sweep, table: pd.DataFrame, out: Path) -> list[Path]:
    """Draw the sweep's [plots] from its result table as <name>_<kind>.png in out."""
    return [save_figure(FIGURES[kind](sweep, table, spec), out / f"{sweep.name}_{kind}.png")
            for kind, spec in sweep.plots.items()]
