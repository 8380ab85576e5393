"""A scenario's plot, `<scenario>.png` (docs/results.md): the mechanism per variant on the
left, the drives on the right.

The left column is the joints' tracking panels, then the panels the variants' models declare
(their registrations' plot_panels): panels of one title are one panel, so variants of
different models that fill the same role (the one-link figure's adjuster travel, spring
length or counterweight position) share it. A variable in metres is drawn in mm, one in
radians in deg.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from harness import registry  # noqa: E402
from harness.io import save_figure  # noqa: E402
from harness.scenarios import Joint, Scenario  # noqa: E402

Conversion = Callable[[np.ndarray], np.ndarray] | None
# a mechanism panel: (title, unit, [(column, conversion), ...]); a column ending in _ref is
# the reference, drawn once in black
Panel = tuple[str, str, list[tuple[str, Conversion]]]

ONE_JOINT_DRIVE_PANELS = (
    ("drive torque", "N m", "tau_drive"),
    ("motor current", "A", "i"),
    ("electrical power", "W", "P_elec"),
    ("energy drawn", "J", "E_drawn"),
)
# a panel's signals in order (then again from the first)
STYLES = ("-", "--", ":", "-.", (0, (5, 1)), (0, (1, 1)), (0, (3, 1, 1, 1, 1, 1)),
          (0, (3, 5, 1, 5)))


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


def panels(scenario: Scenario, models: Sequence[str]) -> tuple[list[Panel], list[tuple]]:
    """(mechanism panels, drive panels) of a scenario's plot of variants of the models: the
    link angle (one joint; Franchetti et al. 2021, Figure 5 (a)) or one tracking panel per
    joint, then `declared_panels`; the drive's torque, current, power and energy drawn (one
    joint) or each drive's effort and all drives' power and energy drawn."""
    one_joint = len(scenario.joints) == 1
    tracking, efforts = [], []
    for joint in scenario.joints:
        revolute = joint.kind == "revolute"
        unit, convert = joint_drawn_in(joint)
        title = (f"(a) link {'angle' if revolute else 'position'}" if one_joint
                 else f"joint {joint.name}")
        tracking.append((title, unit, [(joint.position, convert),
                                       (f"{joint.position}_ref", convert)]))
        efforts.append((f"drive effort {joint.effort} ({joint.motor} motor)",
                        "N m" if revolute else "N", joint.effort))
    drives = list(ONE_JOINT_DRIVE_PANELS) if one_joint else [
        *efforts, ("electrical power, all drives", "W", "P_elec"),
        ("energy drawn, all drives", "J", "E_drawn")]
    return [*tracking, *declared_panels(models)], drives


def plot(results: Sequence[Plotted], scenario: Scenario, path: Path) -> Path:
    """The mechanism per variant (left) and the drives per variant (right), see `panels`:
    a colour per variant, a line style per signal of a panel."""
    mechanism, drives = panels(scenario, [r.model for r in results])
    rows = max(len(mechanism), len(drives))
    fig, axes = plt.subplots(rows, 2, figsize=(13, 3 * rows), sharex=True, squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for row, (title, unit, signals) in enumerate(mechanism):
        ax = axes[row, 0]
        for colour, r in zip(colours, results, strict=False):
            for style, (name, convert) in zip(itertools.cycle(STYLES), signals):
                reference = name.endswith("_ref")
                if name not in r.series or (reference and r is not results[0]):
                    continue
                values = r.series[name].to_numpy()
                ax.plot(r.series.time, convert(values) if convert else values, style,
                        color="k" if reference else colour, lw=1.2)
        # one legend entry per signal shown (line style) and per variant (colour)
        shown = [(style, name) for style, (name, _) in zip(itertools.cycle(STYLES), signals)
                 if any(name in r.series for r in results)]
        handles = [Line2D([], [], ls=style, color="0.4", label=name)
                   for style, name in shown if not name.endswith("_ref")]
        handles += [Line2D([], [], color=colour, label=r.variant)
                    for colour, r in zip(colours, results, strict=False)
                    if any(name in r.series for _, name in shown)]
        handles += [Line2D([], [], ls=style, color="k", label="reference")
                    for style, name in shown if name.endswith("_ref")]
        ax.legend(handles=handles, fontsize=7, ncol=2)
        _decorate(ax, title, unit)
    for row, (title, unit, name) in enumerate(drives):
        ax = axes[row, 1]
        for colour, r in zip(colours, results, strict=False):
            # a several-joint run shows its first joint's signal (<name>_<joint>); a stored
            # run of another layout may have neither
            column = name if name in r.series else next(
                (c for c in r.series.columns if c.startswith(f"{name}_")), None)
            if column is None:
                continue
            ax.plot(r.series.time, r.series[column], color=colour, lw=1.2, label=r.variant)
        ax.legend(fontsize=7)
        _decorate(ax, title, unit)
    for ax in axes[rows - 1:, :].ravel():
        ax.set_xlabel("time [s]")
    for row in range(len(mechanism), rows):
        axes[row, 0].set_visible(False)
    for row in range(len(drives), rows):
        axes[row, 1].set_visible(False)
    fig.suptitle(f"{scenario.name}: mechanism (panels of Franchetti et al. 2021, Fig. 5) "
                 "and drive" if len(scenario.joints) == 1 else
                 f"{scenario.name}: joints, mechanism and drives")
    fig.tight_layout()
    return save_figure(fig, path)


def _decorate(ax: plt.Axes, title: str, unit: str) -> None:
    ax.set_title(title, loc="left", fontsize=10)
    ax.set_ylabel(unit)
    ax.grid(alpha=0.3)
