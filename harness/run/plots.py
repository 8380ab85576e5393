"""A scenario's figures (docs/results.md): `<scenario>.png`, one result set over time, and
`<scenario>_energy.png`, the headline: every variant's energy drawn in each loss set.

The time series (`figure`): a column for the mechanism, then a column per drive. The
mechanism's column is the joints' tracking panels, then the panels the variants' models
declare (their registrations' plot_panels): panels of one title are one panel, so variants
of different models that fill the same role (the one-link figure's adjuster travel, spring
length or counterweight position) share it. A variable in metres is drawn in mm, one in
radians in deg. Each drive's column is its effort, motor current, voltage, electrical power
and energy drawn, for every variant that has that drive. Every axis carries one quantity in
one unit, a colour per variant (the figure's legend), a line style per signal of a panel
(the panel's legend, beside it): no legend covers data.

The headline (`energy_figure`): E_drawn of every variant in every loss set, horizontal bars
on a logarithmic axis, so that a balanced variant's hundredths of a joule and an unbalanced
one's hundred joules both read off it, each value printed at its bar.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd
from matplotlib import rcParams
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter

from harness import registry
from harness.io import save_figure
from harness.scenarios import Joint, Scenario

Conversion = Callable[[np.ndarray], np.ndarray] | None
# a mechanism panel: (title, unit, [(column, conversion), ...]); a column ending in _ref is
# the reference, drawn once in black
Panel = tuple[str, str, list[tuple[str, Conversion]]]

# a drive's panels after its effort: (quantity, unit, column of a one-drive run; a run of
# several drives suffixes it with _<joint>, harness.engines.result.suffix)
DRIVE_SIGNALS = (
    ("motor current", "A", "i"),
    ("voltage", "V", "V"),
    ("electrical power", "W", "P_elec"),
    ("energy drawn", "J", "E_drawn"),
)
# a panel's signals in order (then again from the first)
STYLES = ("-", "--", ":", "-.", (0, (5, 1)), (0, (1, 1)), (0, (3, 1, 1, 1, 1, 1)),
          (0, (3, 5, 1, 5)))
COLUMN_WIDTH = 5.6   # [in] of a column of panels
ROW_HEIGHT = 2.4     # [in] of a row of panels
LOSS_SET_COLOURS = {"ideal": "tab:blue", "realistic": "tab:orange"}
LOSS_SET_LABELS = {"ideal": "ideal", "realistic": "realistic losses"}


class Plotted(Protocol):
    """A variant's run as the plot reads it (a RunResult, or a stored variant's CSV)."""

    variant: str
    model: str
    series: pd.DataFrame


def _to_mm(values: np.ndarray) -> np.ndarray:
    return 1e3 * values


# what a variable's unit is drawn in: (plot unit, conversion)
DRAWN_IN = {"m": ("mm", _to_mm), "rad": ("deg", np.degrees)}


def joint_drawn_in(joint: Joint) -> tuple[str, Conversion]:
    """What a joint's position (and tracking error) is drawn in: deg for a revolute joint,
    mm for a prismatic one (plot unit, conversion from SI)."""
    return DRAWN_IN["rad" if joint.kind == "revolute" else "m"]


def effort_unit(joint: Joint) -> str:
    """The unit of a joint's drive effort: N m on a revolute joint, N on a prismatic one."""
    return "N m" if joint.kind == "revolute" else "N"


def declared_panels(models: Sequence[str]) -> list[Panel]:
    """The models' plot_panels merged by title in order of first appearance, each name once,
    with the conversion its unit (that of the first model declaring it) is drawn in."""
    merged: dict[str, tuple[str, dict[str, None]]] = {}
    units: dict[str, str | None] = {}
    for model in dict.fromkeys(models):
        found = registry.registration(model)
        if found is None or found.physics is None:
            continue
        for title, unit, names in found.plot_panels:
            merged.setdefault(title, (unit, {}))[1].update(dict.fromkeys(names))
        for v in (*found.physics.INPUT_VARIABLES, *found.physics.OUTPUT_VARIABLES):
            units.setdefault(v.name, v.unit)
    return [(title, unit, [(name, DRAWN_IN.get(units.get(name), (None, None))[1])
                           for name in names])
            for title, (unit, names) in merged.items()]


def mechanism_panels(scenario: Scenario, models: Sequence[str]) -> list[Panel]:
    """The mechanism's column: a tracking panel per joint of the scenario (the link angle of
    a one-joint scenario, Franchetti et al. 2021, Figure 5 (a)), then `declared_panels`."""
    tracking = []
    for joint in scenario.joints:
        quantity = "angle" if joint.kind == "revolute" else "position"
        unit, convert = joint_drawn_in(joint)
        title = (f"link {quantity}" if len(scenario.joints) == 1
                 else f"joint {joint.name} {quantity}")
        tracking.append((title, unit, [(joint.position, convert),
                                       (f"{joint.position}_ref", convert)]))
    return [*tracking, *declared_panels(models)]


def drives(scenario: Scenario) -> list[Joint]:
    """Every joint a drive moves in some variant: the scenario's, then the variants' own,
    each once."""
    joints: dict[str, Joint] = {}
    for joint in (*scenario.joints,
                  *(joint for variant in scenario.variants.values() for joint in variant.joints)):
        joints.setdefault(joint.name, joint)
    return list(joints.values())


def drive_column(series: pd.DataFrame, joint: Joint, name: str) -> str | None:
    """The column of a run's series holding the drive on joint's signal name (one of
    DRIVE_SIGNALS', or the joint's effort input, which is never suffixed); None when the run
    does not drive the joint (it has no `<position>_ref`). A run of several drives names its
    drive columns `<name>_<joint>` (its plain P_elec and E_drawn are totals), one of one
    drive plain `<name>`."""
    if f"{joint.position}_ref" not in series:
        return None
    return next((c for c in (f"{name}_{joint.name}", name) if c in series), None)


def drive_panels(joint: Joint) -> list[tuple[str, str, str]]:
    """A drive's column: (title, unit, signal name for `drive_column`) of its effort, then
    of DRIVE_SIGNALS."""
    force = "torque" if joint.kind == "revolute" else "force"
    return [(f"drive {joint.name}: {force} {joint.effort}",
             effort_unit(joint), joint.effort),
            *((f"drive {joint.name}: {quantity}", unit, name)
              for quantity, unit, name in DRIVE_SIGNALS)]


def set_title(scenario: Scenario, what: str, loss_set: str = "ideal") -> str:
    """A figure's title: the scenario (and a loss set other than ideal), what the figure
    shows, the source it cites."""
    where = scenario.name if loss_set == "ideal" else f"{scenario.name}, {loss_set} losses"
    return f"{where}: {what}" + (f" ({scenario.source})" if scenario.source else "")


def figure(results: Sequence[Plotted], scenario: Scenario, loss_set: str = "ideal") -> Figure:
    """The time series of a result set (see the module docstring): the mechanism (left) and
    a column per drive, a colour per variant, a line style per signal of a panel."""
    mechanism = mechanism_panels(scenario, [r.model for r in results])
    joints = drives(scenario)
    columns = [drive_panels(joint) for joint in joints]
    rows = max(len(mechanism), *map(len, columns))
    fig = Figure(figsize=(COLUMN_WIDTH * (1 + len(columns)) + 1.6, 1.0 + ROW_HEIGHT * rows),
                 layout="constrained")
    axes = fig.subplots(rows, 1 + len(columns), sharex=True, squeeze=False)
    colours = dict(zip((r.variant for r in results),
                       itertools.cycle(rcParams["axes.prop_cycle"].by_key()["color"]),
                       strict=False))
    for row, panel in enumerate(mechanism):
        _draw_mechanism_panel(axes[row, 0], panel, results, colours)
    for column, (joint, panels) in enumerate(zip(joints, columns, strict=True), 1):
        for row, (title, unit, name) in enumerate(panels):
            ax = axes[row, column]
            for r in results:
                found = drive_column(r.series, joint, name)
                if found is not None:
                    ax.plot(r.series.time, r.series[found], color=colours[r.variant], lw=1.2)
            _decorate(ax, title, unit)
    axes[0, 0].set_xlim(0.0, scenario.duration)  # the task, on every panel (shared)
    for column, used in enumerate([len(mechanism), *map(len, columns)]):
        for ax in axes[used:, column]:
            ax.set_visible(False)
        axes[used - 1, column].tick_params(labelbottom=True)
        axes[used - 1, column].set_xlabel("time [s]")
    fig.legend(handles=[Line2D([], [], color=colours[r.variant], lw=2, label=r.variant)
                        for r in results],
               loc="outside lower center", ncols=min(len(results), 6), fontsize=9,
               title="variant", title_fontsize=9)
    fig.suptitle(set_title(scenario, "mechanism and drives over the task", loss_set))
    return fig


def plot(results: Sequence[Plotted], scenario: Scenario, path: Path,
         loss_set: str = "ideal") -> Path:
    """Write the result set's time series (`figure`) as PNG at path."""
    return save_figure(figure(results, scenario, loss_set), path)


def _draw_mechanism_panel(ax: Axes, panel: Panel, results: Sequence[Plotted],
                          colours: Mapping[str, str]) -> None:
    """One panel of the mechanism's column, its signals' line styles in a legend beside it."""
    title, unit, signals = panel
    styled = list(zip(itertools.cycle(STYLES), signals))
    for r in results:
        for style, (name, convert) in styled:
            reference = name.endswith("_ref")
            if name not in r.series or (reference and r is not results[0]):
                continue
            values = r.series[name].to_numpy()
            ax.plot(r.series.time, convert(values) if convert else values, ls=style,
                    color="k" if reference else colours[r.variant], lw=1.2)
    shown = [(style, name) for style, (name, _) in styled
             if any(name in r.series for r in results)]
    handles = [Line2D([], [], ls=style, color="k" if name.endswith("_ref") else "0.4",
                      label="reference" if name.endswith("_ref") else name)
               for style, name in shown]
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  borderaxespad=0.0, fontsize=8, handlelength=2.5)
    _decorate(ax, title, unit)


def _decorate(ax: Axes, title: str, unit: str) -> None:
    ax.set_title(title, loc="left", fontsize=10)
    ax.set_ylabel(unit)
    ax.grid(alpha=0.3)


def energy_figure(scenario: Scenario, tables: Mapping[str, pd.DataFrame]) -> Figure:
    """The headline of a scenario: each variant's E_drawn [J] in each loss set (tables: loss
    set -> its summary), horizontal bars on a logarithmic axis, the value printed at each
    bar; a variant a loss set did not run, or whose E_drawn is not positive (no place on a
    log axis), gets its value or 'not run' in place of the bar. The scenario's variants
    first, in its order, then those only a summary has; baselines marked."""
    energies = {loss_set: dict(zip(table.variant, table.E_drawn, strict=True))
                for loss_set, table in tables.items()}
    variants = list(dict.fromkeys([*scenario.variants,
                                   *(v for values in energies.values() for v in values)]))
    positive = [e for values in energies.values() for e in values.values() if e > 0]
    low = min(positive) / 5.0 if positive else 0.1  # the shortest bar spans 0.7 decades
    high = 8.0 * max(positive) if positive else 10.0  # room for the values printed
    height = 0.8 / max(len(energies), 1)
    fig = Figure(figsize=(9.0, 1.4 + 0.32 * len(variants) * max(len(energies), 1)),
                 layout="constrained")
    ax = fig.subplots()
    ax.set_xscale("log")
    ax.set_xlim(low, high)
    for k, (loss_set, values) in enumerate(energies.items()):
        colour = LOSS_SET_COLOURS.get(loss_set, f"C{k + 2}")
        for row, variant in enumerate(variants):
            y = row + (k - (len(energies) - 1) / 2) * height
            value = values.get(variant, math.nan)
            if value > 0:
                ax.barh(y, value - low, height * 0.9, left=low, color=colour)
                text, at = f"{value:.3g} J", value * 1.15
            else:
                text, at = ("not run" if math.isnan(value) else f"{value:.3g} J"), low * 1.15
            ax.text(at, y, text, va="center", fontsize=8)
    baselines = set(scenario.baselines.values())
    ax.set_yticks(range(len(variants)),
                  [f"{v} (baseline)" if v in baselines else v for v in variants])
    ax.set_ylim(len(variants) - 0.5, -0.5)  # the first variant on top
    ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    ax.set_xlabel("energy drawn from the supply over the task, E_drawn [J] (log scale)")
    ax.xaxis.grid(True, which="major", alpha=0.3)
    ax.legend(handles=[Patch(color=LOSS_SET_COLOURS.get(s, f"C{k + 2}"),
                             label=LOSS_SET_LABELS.get(s, s))
                       for k, s in enumerate(energies)],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=9)
    fig.suptitle(set_title(scenario, "energy each variant's drives draw"))
    return fig
