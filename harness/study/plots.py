"""A study's figures (docs/study.md), each answering one question:

- energy.png: how much does each variant draw over the tasks? Per loss set, each variant's
  E_drawn [J] on a logarithmic axis: a bar from the 5 % to the 95 % quantile with the median
  marked, the medians printed in a column beside the axes;
- dependence.png: where does the ranking change? Per loss set (rows) and task figure
  (columns), each variant's median E_drawn over the reference's in bins of tasks, on a
  logarithmic axis; a colour and a marker per variant, named in the legend under the panels.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from harness.run.plots import (
    LOSS_SET_COLOURS,
    LOSS_SET_LABELS,
    MARKERS,
    fit_suptitle,
    readable_log,
    show_coinciding,
    significant,
)
from harness.study.statistics import TASK_AXES, energies

MARGIN = 1.3  # the energy axis's room beyond the outermost quantiles (a factor, log scale)


def energy_figure(name: str, runs: pd.DataFrame, variants: list[str], tasks: int) -> Figure:
    """E_drawn of each variant over the study's tasks (see the module docstring)."""
    tables = energies(runs, variants)
    fig = Figure(figsize=(9.0, 2.0 + 0.34 * len(variants) * len(tables)), layout="constrained")
    ax = fig.subplots()
    ax.set_xscale("log")
    height = 0.8 / max(len(tables), 1)
    lows, highs = [], []
    for k, (loss_set, wide) in enumerate(tables.items()):
        colour = LOSS_SET_COLOURS.get(loss_set, f"C{k + 2}")
        for row, variant in enumerate(variants):
            y = row + (k - (len(tables) - 1) / 2) * height
            low, median, high = np.quantile(wide[variant], (0.05, 0.5, 0.95))
            lows.append(low)
            highs.append(high)
            ax.barh(y, high - low, height * 0.85, left=low, color=colour, alpha=0.45)
            ax.plot([median, median], [y - height * 0.42, y + height * 0.42], color=colour,
                    lw=2)
            ax.annotate(f"{significant(median)} J", (1.0, y), xytext=(6, 0), fontsize=8,
                        xycoords=("axes fraction", "data"), textcoords="offset points",
                        va="center", color=colour, annotation_clip=False)
    if tables:
        ax.set_xlim(min(lows) / MARGIN, max(highs) * MARGIN)
        ax.annotate("median", (1.0, 1.0), xytext=(6, 4), xycoords="axes fraction",
                    textcoords="offset points", fontsize=8, va="bottom")
    ax.set_yticks(range(len(variants)), variants)
    ax.set_ylim(len(variants) - 0.5, -0.5)
    readable_log(ax.xaxis)
    ax.set_xlabel("energy drawn from the supply over a task, E_drawn [J] (log scale)")
    ax.xaxis.grid(True, which="major", alpha=0.3)
    fig.legend(handles=[*(Patch(color=LOSS_SET_COLOURS.get(s, f"C{k + 2}"), alpha=0.6,
                                label=f"{LOSS_SET_LABELS.get(s, s)}: 5 % to 95 % of the tasks")
                          for k, s in enumerate(tables)),
                        Line2D([], [], color="0.3", lw=2, label="median")],
               loc="outside lower center", ncols=len(tables) + 1, fontsize=8)
    fit_suptitle(fig, f"{name}: energy each variant's drives draw over {tasks} random tasks")
    return fig


def bins_text(table: pd.DataFrame) -> str:
    """The bins of a dependence table in words: 'quartiles of the tasks (50 tasks each)', or
    '3 bins of 1 to 2 tasks' where values repeat or tasks are few."""
    bins = table.drop_duplicates(["losses", "axis", "low", "high"])
    per_axis, counts = bins.groupby(["losses", "axis"]).size(), bins.tasks
    sizes = (f"{counts.min()} tasks each" if counts.min() == counts.max()
             else f"{counts.min()} to {counts.max()} tasks")
    if per_axis.min() == per_axis.max() == 4 and counts.min() == counts.max():
        return f"quartiles of the tasks ({sizes})"
    number = (f"{per_axis.min()}" if per_axis.min() == per_axis.max()
              else f"{per_axis.min()} to {per_axis.max()}")
    return f"{number} bins of {sizes}"


def dependence_figure(name: str, table: pd.DataFrame, reference: str) -> Figure | None:
    """The ratio to the reference by bins of each task figure (see the module docstring);
    None without rows (a study whose tasks vary in neither figure)."""
    if table.empty:
        return None
    sets = list(dict.fromkeys(table.losses))
    axes_names = [a for a in TASK_AXES if a in set(table.axis)]
    variants = list(dict.fromkeys(table.variant))
    style = {v: (f"C{k}", MARKERS[k % len(MARKERS)]) for k, v in enumerate(variants)}
    fig = Figure(figsize=(5.2 * len(axes_names) + 1.6, 1.4 + 3.2 * len(sets)),
                 layout="constrained")
    grid = fig.subplots(len(sets), len(axes_names), squeeze=False, sharey=True)
    for r, loss_set in enumerate(sets):
        for c, axis in enumerate(axes_names):
            ax = grid[r][c]
            rows = table[(table.losses == loss_set) & (table.axis == axis)]
            for variant, group in rows.groupby("variant", sort=False):
                centre = (group.low.to_numpy() + group.high.to_numpy()) / 2.0
                colour, marker = style[variant]
                ax.plot(centre, group.ratio_median, marker=marker, color=colour)
            ax.set_yscale("log")
            readable_log(ax.yaxis)
            ax.grid(alpha=0.3)
            ax.set_xlabel(TASK_AXES[axis])
            if c == 0:
                ax.set_ylabel(f"E_drawn / E_drawn({reference}) [-]")
            ax.set_title(LOSS_SET_LABELS.get(loss_set, loss_set), loc="left", fontsize=10)
    for ax in grid.flat:  # the shared limits known
        show_coinciding(ax.get_lines())
    fig.legend(handles=[Line2D([], [], color=colour, marker=marker, label=variant)
                        for variant, (colour, marker) in style.items()],
               loc="outside lower center", ncols=min(len(variants), 4), fontsize=9)
    fit_suptitle(fig, f"{name}: median energy ratio to {reference} in "
                      f"{bins_text(table)}, by task figure")
    return fig
