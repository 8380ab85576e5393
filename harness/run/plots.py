"""A scenario's figures (docs/results.md): `<scenario>.png`, one result set over time, and
`<scenario>_energy.png`, the headline: every variant's energy drawn in each loss set.

The time series (`figure`): a column for the mechanism, then a column per drive. The
mechanism's column is the joints' tracking panels, then the panels the variants' models
declare (their registrations' plot_panels): panels of one title are one panel, so variants
of different models that fill the same role (the one-link figure's adjuster travel, spring
length or counterweight position) share it. A variable in metres is drawn in mm, one in
radians in deg. Each drive's column is its effort, motor current, voltage, electrical power
and energy drawn, for every variant that has that drive; the energy drawn on a symmetric log
axis where the variants' totals span decades. Panels are lettered down each column, left to
right. Every axis carries one quantity (the panel's title) in one unit, a colour per variant
(the figure's legend), a line style per signal of a panel (the panel's legend, beside it):
no legend covers data. Lines that coincide carry markers of their own (`show_coinciding`).

The headline (`energy_figure`): E_drawn of every variant in every loss set, horizontal bars
on a logarithmic axis, so that a balanced variant's hundredths of a joule and an unbalanced
one's hundred joules both read off it, each value printed at its bar.

The helpers every figure of the harness draws with: `significant` (values printed with three
significant figures), `readable_log` (a logarithmic axis with at least three labelled ticks),
`show_coinciding`, `fit_suptitle` (a title wrapped to the figure's width) and `column_unit`.
"""

from __future__ import annotations

import itertools
import math
import textwrap
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd
from matplotlib import rcParams
from matplotlib.axes import Axes
from matplotlib.axis import Axis
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter, Locator, MaxNLocator, NullFormatter

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


# a logarithmic axis's major ticks: the first of these multiples of each decade that puts
# MIN_LOG_TICKS inside the view (then linear ticks, in a view narrower than that)
LOG_SUBS = ((1.0,), (1.0, 2.0, 5.0), (1.0, 2.0, 3.0, 5.0), tuple(float(k) for k in range(1, 10)))
MIN_LOG_TICKS = 3
# lines of a panel coincide where they differ by less than this fraction of its y range
# at 90 % of their points or more; each then gets markers (MARKERS, about MARKS_PER_LINE)
COINCIDE = 0.01
COINCIDE_SHARE = 0.9
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
MARKS_PER_LINE = 12
NO_MARKER = (None, "None", "none", "", " ")


def significant(value: float, figures: int = 3) -> str:
    """value with `figures` significant figures, trailing zeros kept and no exponent:
    13 -> '13.0', 0.0747 -> '0.0747', 1234 -> '1230'."""
    if value == 0 or not math.isfinite(value):
        return f"{value:g}"
    rounded = float(f"{value:.{figures}g}")
    return f"{rounded:.{max(0, figures - 1 - math.floor(math.log10(abs(rounded))))}f}"


class LogTicks(Locator):
    """Major ticks of a logarithmic axis: decades, or 1-2-5, 1-2-3-5 or every multiple of a
    decade, the first that puts MIN_LOG_TICKS ticks inside the view."""

    def __call__(self) -> list[float]:
        return self.tick_values(*self.axis.get_view_interval())

    def tick_values(self, vmin: float, vmax: float) -> list[float]:
        low, high = sorted((vmin, vmax))
        if not (0 < low < high < math.inf):
            return []
        decades = range(math.floor(math.log10(low)), math.ceil(math.log10(high)) + 1)
        for subs in LOG_SUBS:
            ticks = [float(f"{s * 10.0 ** e:.12g}") for e in decades for s in subs]
            inside = [t for t in ticks if low * (1 - 1e-9) <= t <= high * (1 + 1e-9)]
            if len(inside) >= MIN_LOG_TICKS:
                return inside
        return [t for t in MaxNLocator(MIN_LOG_TICKS + 1).tick_values(low, high)
                if low <= t <= high]


def readable_log(axis: Axis) -> None:
    """Label a logarithmic axis (set its scale first) at LogTicks with plain numbers ('0.1',
    '20'), its minor ticks unlabelled; a symmetric log axis at its own ticks, the same way."""
    if axis.get_scale() == "log":
        axis.set_major_locator(LogTicks())
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(NullFormatter())


def coinciding(lines: Sequence[Line2D], tolerance: float = COINCIDE) -> list[list[Line2D]]:
    """Groups (in drawing order) of the lines of one axes each close (`_close`) to another of
    its group: within tolerance times the axes' y range as its scale draws it (decades on a
    log axis; set the limits first). Lines of two styles are not grouped: each shows
    through the other's gaps."""
    if not lines:
        return []
    scale = lines[0].axes.yaxis.get_transform()
    values = [scale.transform(np.asarray(line.get_ydata(), float)) for line in lines]
    limit = tolerance * float(np.ptp(scale.transform(np.asarray(lines[0].axes.get_ylim()))))
    groups: list[list[int]] = []
    for i, line in enumerate(lines):
        joined = next((group for group in groups for k in group if _close(
            line, lines[k], values[i], values[k], limit)), None)
        if joined is None:
            groups.append([i])
        else:
            joined.append(i)
    return [[lines[i] for i in group] for group in groups if len(group) > 1]


def _close(line: Line2D, other: Line2D, y: np.ndarray, y_other: np.ndarray,
           limit: float) -> bool:
    """Whether two lines of one style on the same x values are within limit of each other
    at COINCIDE_SHARE of their points."""
    x, x_other = (np.asarray(a.get_xdata(), float) for a in (line, other))
    return (line.get_linestyle() == other.get_linestyle() and x.shape == x_other.shape
            and np.allclose(x, x_other, equal_nan=True)
            and float(np.mean(np.abs(y - y_other) <= limit)) >= COINCIDE_SHARE)


def show_coinciding(lines: Sequence[Line2D]) -> bool:
    """Give each line of a coinciding group (`coinciding`) markers that the others leave in
    sight: where it has none, a shape of its own staggered along the line; where the group's
    markers fall on the same points (a line of few points), larger the earlier it is drawn,
    nested. Returns whether any lines coincide."""
    groups = coinciding(lines)
    for group in groups:
        for k, line in enumerate(group):
            step = len(line.get_xdata()) // MARKS_PER_LINE
            unmarked = line.get_marker() in NO_MARKER
            staggered = step > 1 and unmarked
            if staggered:
                line.set_markevery((k * step // len(group), step))
            if unmarked:
                line.set_marker(MARKERS[k % len(MARKERS)])
            line.set_markersize(4.0 if staggered else 4.0 + 2.5 * (len(group) - 1 - k))
    return bool(groups)


def fit_suptitle(fig: Figure, text: str, fontsize: float = 12.0) -> None:
    """The figure's title, wrapped to lines that fit its width."""
    width = max(20, int(fig.get_figwidth() * 72.0 / (0.6 * fontsize)))
    fig.suptitle("\n".join(textwrap.wrap(text, width)), fontsize=fontsize)


# the units of the harness's own columns of a run's series (a joint's suffixed the same)
SERIES_UNITS = {"time": "s", **{name: unit for _, unit, name in DRIVE_SIGNALS}, "E_in": "J",
                "W_bond_drive": "J", "W_bond_joint": "J", "W_bond_error": "J"}


def column_unit(name: str) -> str | None:
    """The SI unit of a column of a run's series ('N m' for N.m), a reference `<name>_ref`
    that of its variable; None for a name no mechanism or drive has."""
    name = name.removesuffix("_ref")
    units = {v.name: v.unit for r in registry.mechanisms().values()
             for v in (*r.physics.INPUT_VARIABLES, *r.physics.OUTPUT_VARIABLES)}
    base = next((b for b in SERIES_UNITS if name == b or name.startswith(f"{b}_")), None)
    unit = units.get(name) or SERIES_UNITS.get(base or "")
    return unit.replace(".", " ") if unit else None


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
    letters = iter("abcdefghijklmnopqrstuvwxyz")
    marked = [_draw_mechanism_panel(axes[row, 0], panel, results, colours, next(letters))
              for row, panel in enumerate(mechanism)]
    for column, (joint, panels) in enumerate(zip(joints, columns, strict=True), 1):
        for row, (title, unit, name) in enumerate(panels):
            ax = axes[row, column]
            lines = [ax.plot(r.series.time, r.series[found], color=colours[r.variant],
                             lw=1.2)[0]
                     for r in results if (found := drive_column(r.series, joint, name))]
            if name == "E_drawn":
                _log_if_decades(ax, lines)
            marked.append(show_coinciding(lines))
            _decorate(ax, f"({next(letters)}) {title}", unit)
    axes[0, 0].set_xlim(0.0, scenario.duration)  # the task, on every panel (shared)
    for column, used in enumerate([len(mechanism), *map(len, columns)]):
        for ax in axes[used:, column]:
            ax.set_visible(False)
        axes[used - 1, column].tick_params(labelbottom=True)
        axes[used - 1, column].set_xlabel("time [s]")
    fig.legend(handles=[Line2D([], [], color=colours[r.variant], lw=2, label=r.variant)
                        for r in results],
               loc="outside lower center", ncols=min(len(results), 6), fontsize=9,
               title="variant" + (" (lines that coincide carry markers)" if any(marked)
                                  else ""), title_fontsize=9)
    fig.suptitle(set_title(scenario, "mechanism and drives over the task", loss_set))
    return fig


def plot(results: Sequence[Plotted], scenario: Scenario, path: Path,
         loss_set: str = "ideal") -> Path:
    """Write the result set's time series (`figure`) as PNG at path."""
    return save_figure(figure(results, scenario, loss_set), path)


def _draw_mechanism_panel(ax: Axes, panel: Panel, results: Sequence[Plotted],
                          colours: Mapping[str, str], letter: str) -> bool:
    """One panel of the mechanism's column, its signals' line styles in a legend beside it;
    whether lines of it coincide (`show_coinciding`)."""
    title, unit, signals = panel
    styled = list(zip(itertools.cycle(STYLES), signals))
    lines = []
    for r in results:
        for style, (name, convert) in styled:
            reference = name.endswith("_ref")
            if name not in r.series or (reference and r is not results[0]):
                continue
            values = r.series[name].to_numpy()
            line, = ax.plot(r.series.time, convert(values) if convert else values, ls=style,
                            color="k" if reference else colours[r.variant], lw=1.2,
                            zorder=2.5 if reference else 2.0)  # the reference over all
            if not reference:  # drawn once, in black, over every variant's
                lines.append(line)
    shown = [(style, name) for style, (name, _) in styled
             if any(name in r.series for r in results)]
    handles = [Line2D([], [], ls=style, color="k" if name.endswith("_ref") else "0.4",
                      label="reference" if name.endswith("_ref") else name)
               for style, name in shown]
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  borderaxespad=0.0, fontsize=8, handlelength=2.5)
    _decorate(ax, f"({letter}) {title}", unit)
    return show_coinciding(lines)


def _log_if_decades(ax: Axes, lines: Sequence[Line2D]) -> None:
    """A symmetric log y axis when the lines' final values span decades (self-regulation's
    hundredths of a joule beside tens), linear up to the decade below half the smallest."""
    finals = [float(line.get_ydata()[-1]) for line in lines]
    positive = [v for v in finals if v > 0 and math.isfinite(v)]
    if len(positive) > 1 and max(positive) > 30.0 * min(positive):
        ax.set_yscale("symlog", linthresh=10.0 ** math.floor(math.log10(min(positive) / 2)))
        readable_log(ax.yaxis)


def _decorate(ax: Axes, title: str, unit: str) -> None:
    ax.set_title(title, loc="left", fontsize=10)
    ax.set_ylabel(f"[{unit}]")
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
                text, at = f"{significant(value)} J", value * 1.15
            else:
                text = "not run" if math.isnan(value) else f"{significant(value)} J"
                at = low * 1.15
            ax.text(at, y, text, va="center", fontsize=8)
    baselines = set(scenario.baselines.values())
    ax.set_yticks(range(len(variants)),
                  [f"{v} (baseline)" if v in baselines else v for v in variants])
    ax.set_ylim(len(variants) - 0.5, -0.5)  # the first variant on top
    readable_log(ax.xaxis)
    ax.set_xlabel("energy drawn from the supply over the task, E_drawn [J] (log scale)")
    ax.xaxis.grid(True, which="major", alpha=0.3)
    ax.legend(handles=[Patch(color=LOSS_SET_COLOURS.get(s, f"C{k + 2}"),
                             label=LOSS_SET_LABELS.get(s, s))
                       for k, s in enumerate(energies)],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=9)
    fig.suptitle(set_title(scenario, "energy each variant's drives draw"))
    return fig
