"""A study's figures (docs/study.md), each answering one question:

- energy.png: how much does each variant draw over the tasks? Per loss set, each variant's
  E_drawn [J] on a logarithmic axis: a box from the 5 % to the 95 % quantile with the
  median marked and printed;
- dependence.png: where does the ranking change? Per loss set (rows) and task figure
  (columns), each variant's median E_drawn over the reference's in bins of tasks, its name
  at the right end of its line (no legend over data).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter

from harness.run.plots import LOSS_SET_COLOURS, LOSS_SET_LABELS
from harness.study.statistics import TASK_AXES, energies


def energy_figure(name: str, runs: pd.DataFrame, variants: list[str], tasks: int) -> Figure:
    """E_drawn of each variant over the study's tasks (see the module docstring)."""
    tables = energies(runs, variants)
    fig = Figure(figsize=(9.0, 1.6 + 0.34 * len(variants) * len(tables)), layout="constrained")
    ax = fig.subplots()
    ax.set_xscale("log")
    height = 0.8 / max(len(tables), 1)
    for k, (loss_set, wide) in enumerate(tables.items()):
        colour = LOSS_SET_COLOURS.get(loss_set, f"C{k + 2}")
        for row, variant in enumerate(variants):
            y = row + (k - (len(tables) - 1) / 2) * height
            low, median, high = np.quantile(wide[variant], (0.05, 0.5, 0.95))
            ax.barh(y, high - low, height * 0.85, left=low, color=colour, alpha=0.45)
            ax.plot([median, median], [y - height * 0.42, y + height * 0.42], color=colour,
                    lw=2)
            ax.text(high * 1.15, y, f"{median:.3g} J", va="center", fontsize=8)
    ax.set_yticks(range(len(variants)), variants)
    ax.set_ylim(len(variants) - 0.5, -0.5)
    left, right = ax.get_xlim()
    ax.set_xlim(left, right * 8.0)   # room for the medians printed
    ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    ax.set_xlabel("energy drawn from the supply over a task, E_drawn [J] (log scale; "
                  "bar: 5 % to 95 % of the tasks, line and value: median)")
    ax.xaxis.grid(True, which="major", alpha=0.3)
    ax.legend(handles=[Patch(color=LOSS_SET_COLOURS.get(s, f"C{k + 2}"), alpha=0.6,
                             label=LOSS_SET_LABELS.get(s, s)) for k, s in enumerate(tables)],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=9)
    fig.suptitle(f"{name}: energy each variant's drives draw over {tasks} random tasks")
    return fig


def dependence_figure(name: str, table: pd.DataFrame, reference: str) -> Figure | None:
    """The ratio to the reference by bins of each task figure (see the module docstring);
    None without rows (a study whose tasks vary in neither figure)."""
    if table.empty:
        return None
    sets = list(dict.fromkeys(table.losses))
    axes_names = [a for a in TASK_AXES if a in set(table.axis)]
    fig = Figure(figsize=(5.2 * len(axes_names) + 1.6, 3.4 * len(sets)), layout="constrained")
    grid = fig.subplots(len(sets), len(axes_names), squeeze=False, sharey=True)
    for r, loss_set in enumerate(sets):
        for c, axis in enumerate(axes_names):
            ax = grid[r][c]
            rows = table[(table.losses == loss_set) & (table.axis == axis)]
            for k, (variant, group) in enumerate(rows.groupby("variant", sort=False)):
                centre = (group.low.to_numpy() + group.high.to_numpy()) / 2.0
                ax.plot(centre, group.ratio_median, marker="o", color=f"C{k}")
                ax.annotate(variant, (centre[-1], group.ratio_median.iloc[-1]),
                            xytext=(6, 0), textcoords="offset points", va="center",
                            fontsize=7, color=f"C{k}", annotation_clip=False)
            ax.set_yscale("log")
            ax.grid(alpha=0.3)
            ax.set_xlabel(TASK_AXES[axis])
            if c == 0:
                ax.set_ylabel(f"E_drawn / E_drawn({reference}) [-]")
            ax.set_title(LOSS_SET_LABELS.get(loss_set, loss_set), loc="left", fontsize=10)
            ax.margins(x=0.25)
    fig.suptitle(f"{name}: median energy ratio to {reference} in quartiles of the tasks")
    return fig
