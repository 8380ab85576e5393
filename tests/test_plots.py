"""A scenario's figures (harness.run.plots), read through matplotlib's objects: the time
series' panels come from the registrations, every drive of every variant is drawn, each axis
carries one unit, no legend covers data, the titles cite the scenario's source, and the
headline's logarithmic axis shows every variant in both loss sets."""

from __future__ import annotations

import re
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import figure_checks as checks
import numpy as np
import pandas as pd
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from harness import registry
from harness import scenarios as scenario_files
from harness.engines.result import suffix
from harness.run import plots, results
from harness.scenarios import losses

MECHANISMS = registry.mechanisms()
SHIPPED = scenario_files.available()
# what the harness's own signals are drawn in: drive effort, current, voltage, power, energy
DRIVE_UNITS = {"N m", "N", "A", "V", "W", "J"}


def drawn_unit(unit: str) -> str:
    """The unit a variable of the unit is drawn in: mm for m, deg for rad, N m for N.m."""
    return plots.DRAWN_IN.get(unit, (unit.replace(".", " "), None))[0]


def known_units() -> set[str]:
    """Every single unit an axis may carry: those the mechanisms' variables are drawn in and
    the drives'."""
    return DRIVE_UNITS | {drawn_unit(v.unit) for r in MECHANISMS.values()
                          for v in (*r.physics.INPUT_VARIABLES, *r.physics.OUTPUT_VARIABLES)
                          if v.unit}


@pytest.mark.parametrize("model", sorted(MECHANISMS))
def test_every_plot_panel_draws_variables_of_its_model_in_the_panel_unit(model: str) -> None:
    """Every name of a registration's plot_panels is an input or output of its physics, drawn
    (mm for m, deg for rad) in its panel's one unit."""
    physics = MECHANISMS[model].physics
    units = {v.name: v.unit for v in (*physics.INPUT_VARIABLES, *physics.OUTPUT_VARIABLES)}
    for title, unit, names in MECHANISMS[model].plot_panels:
        assert names, title
        for name in names:
            assert name in units, (title, name)
            assert drawn_unit(units[name]) == unit, (title, name, units[name])


def test_panels_of_one_title_are_one_panel_in_order_of_appearance() -> None:
    """The one-link models' panels merge by title: each name once, first model first, metres
    drawn in mm and kilograms as they are."""
    merged = plots.declared_panels(["SelfRegulatingBalancer", "CiupituBalancer",
                                    "SelfRegulatingBalancer", "ActiveSpringBalancer"])
    names = {title: [name for name, _ in signals] for title, _, signals in merged}
    assert list(names) == ["energies", "adjuster travel", "payload",
                           "spring length or counterweight position"]
    assert names["energies"] == ["E_p", "E_e", "E_t"]
    assert names["adjuster travel"] == ["delta_b", "q"]
    assert names["payload"] == ["payload"]
    assert names["spring length or counterweight position"] == ["x", "OB", "l_s"]
    conversions = {name: convert for _, _, signals in merged for name, convert in signals}
    assert conversions["x"](np.array([0.25])) == pytest.approx([250.0])
    assert conversions["payload"] is None and conversions["E_p"] is None
    reversed_order = plots.declared_panels(["CiupituBalancer", "SelfRegulatingBalancer"])
    assert [title for title, _, _ in reversed_order] == [
        "energies", "payload", "spring length or counterweight position", "adjuster travel"]
    assert [name for name, _ in reversed_order[2][2]] == ["OB", "x"]


def test_each_variant_draws_the_panel_signals_it_has(tmp_path: Path) -> None:
    """In the one-joint figure, each variant draws the panel signals its series has (colour
    per variant, line style per signal), the reference once, in the units of the panel;
    `plot` writes the figure as PNG."""
    time_ = np.linspace(0.0, 1.0, 5)
    common = {"time": time_, "theta": time_, "theta_ref": time_, "E_p": time_,
              "payload": 0 * time_, "tau_drive": time_, "i": time_, "V": time_,
              "P_elec": time_, "E_drawn": time_}
    runs = [SimpleNamespace(variant="a", model="SelfRegulatingBalancer",
                            series=pd.DataFrame({**common, "x": 0.1 + 0 * time_})),
            SimpleNamespace(variant="b", model="CiupituBalancer",
                            series=pd.DataFrame({**common, "OB": 0.2 + 0 * time_}))]
    scenario = scenario_files.load("franchetti2021")
    fig = plots.figure(runs, scenario)
    axes = {titled(ax): ax for ax in fig.axes if ax.get_visible()}
    geometry = axes["spring length or counterweight position"]
    lines = [(line.get_linestyle(), to_hex(line.get_color()), line.get_ydata()[0])
             for line in geometry.get_lines()]
    assert lines == [("-", "#1f77b4", pytest.approx(100.0)),
                     ("--", "#ff7f0e", pytest.approx(200.0))]
    angle = axes["link angle"]
    assert len(angle.get_lines()) == 3  # theta of each variant, the reference of the first
    assert angle.get_lines()[1].get_ydata()[-1] == pytest.approx(np.degrees(1.0))
    assert axes["payload"].get_ylabel() == "[kg]"
    assert axes["adjuster travel"].get_ylabel() == "[mm]"
    assert not axes["drive q: motor current"].get_lines()  # neither drives the anchor
    path = plots.plot(runs, scenario, tmp_path / "p.png")
    assert path.read_bytes().startswith(b"\x89PNG")


# ---- the time series of every shipped scenario, from runs named as the engines name them

def column_value(variant: int, joint: int, signal: int) -> float:
    """The level of a made-up run's column: unique per variant, drive and signal."""
    return 1000.0 * (variant + 1) + 100.0 * joint + signal


def made_up_runs(scenario: scenario_files.Scenario) -> list[SimpleNamespace]:
    """A run per variant with the columns harness.engines.result writes (drive columns
    suffixed by joint where the variant drives several, totals then unsuffixed) and the
    variables its model's panels draw: levels from column_value plus a small wave."""
    times = np.linspace(0.0, scenario.duration, 30)
    wave = 0.1 * np.sin(times)
    runs = []
    for k, (name, variant) in enumerate(scenario.variants.items()):
        resolved = scenario.for_variant(variant)
        model = variant.model or scenario.model
        panels = registry.registration(model).plot_panels
        columns = {n: column_value(k, 9, i) + wave
                   for i, n in enumerate(n for _, _, names in panels for n in names)}
        for j, joint in enumerate(resolved.joints):
            columns[joint.position] = columns[f"{joint.position}_ref"] = wave
            columns[joint.effort] = column_value(k, j, 0) + wave
            for i, signal in enumerate(("i", "V", "P_elec", "E_drawn"), 1):
                columns[f"{signal}{suffix(resolved, joint)}"] = column_value(k, j, i) + wave
        if len(resolved.joints) > 1:
            for signal in ("P_elec", "E_drawn"):
                columns[signal] = sum(columns[f"{signal}_{joint.name}"]
                                      for joint in resolved.joints)
        runs.append(SimpleNamespace(variant=name, model=model,
                                    series=pd.DataFrame({"time": times, **columns})))
    return runs


def drawn(name: str) -> Figure:
    """The time series of a shipped scenario from made-up runs, laid out."""
    scenario = scenario_files.load(name)
    fig = plots.figure(made_up_runs(scenario), scenario)
    FigureCanvasAgg(fig).draw()
    return fig


def headline(name: str) -> tuple[Figure, dict[str, pd.DataFrame]]:
    """The headline figure of a shipped scenario from its committed summaries, laid out."""
    scenario = scenario_files.load(name)
    tables = {s: pd.read_csv(losses.result_folder(results.RESULTS_DIR, scenario, s)
                             / "summary.csv") for s in losses.LOSS_SETS}
    fig = plots.energy_figure(scenario, tables)
    FigureCanvasAgg(fig).draw()
    return fig, tables


def titled(ax: object) -> str:
    """A panel's title without its letter: 'link angle' of '(a) link angle'."""
    return re.sub(r"^\([a-z]\) ", "", ax.get_title(loc="left"))


def visible_axes(fig: Figure) -> list:
    return [ax for ax in fig.axes if ax.get_visible()]


def assert_every_drive_of_every_variant_is_drawn(fig: Figure,
                                                 scenario: scenario_files.Scenario) -> None:
    """Each drive's column (effort, current, voltage, power, energy drawn) draws that drive's
    signal of every variant driving it, once; the figure's legend names every variant."""
    axes = {titled(ax): ax for ax in visible_axes(fig)}
    joints = {joint.name for v in scenario.variants.values()
              for joint in scenario.for_variant(v).joints}
    for joint in joints:
        # (variant index, the joint's index among the variant's drives) of each driving it
        driving = [(k, order.index(joint)) for k, order in enumerate(
            [j.name for j in scenario.for_variant(v).joints] for v in scenario.variants.values())
            if joint in order]
        titles = [t for t in axes if t.startswith(f"drive {joint}")]
        assert len(titles) == 5, titles
        for signal, title in enumerate(titles):
            levels = sorted(round(line.get_ydata()[0]) for line in axes[title].get_lines())
            assert levels == [column_value(k, j, signal) for k, j in driving], title
    assert fig.legends[0].get_title().get_text().startswith("variant")
    assert [t.get_text() for t in fig.legends[0].get_texts()] == list(scenario.variants)


def assert_every_line_lies_inside_its_axes(fig: Figure) -> None:
    """Every point of every plotted line is inside its axes' limits."""
    for ax in visible_axes(fig):
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        for line in ax.get_lines():
            x, y = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
            assert x.size and x0 <= x.min() and x.max() <= x1, titled(ax)
            assert y0 <= y.min() and y.max() <= y1, titled(ax)


def assert_each_axis_carries_one_unit(fig: Figure) -> None:
    """Every y label is one unit in brackets (no 'mm | kg', no 'N m | N'), the panel's
    title its quantity; the bottom panel of each column reads time [s]."""
    units = {f"[{unit}]" for unit in known_units()}
    for ax in visible_axes(fig):
        assert ax.get_ylabel() in units, (titled(ax), ax.get_ylabel())
    assert {ax.get_xlabel() for ax in visible_axes(fig)} == {"", "time [s]"}
    columns = {round(ax.get_position().x0, 3) for ax in visible_axes(fig)}
    assert sum(ax.get_xlabel() == "time [s]" for ax in visible_axes(fig)) == len(columns)


def assert_no_legend_covers_data(fig: Figure) -> None:
    """The figure has legends, and none covers data (figure_checks.legend_over_data)."""
    assert [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend())]
    assert checks.legend_over_data(fig) == []


@pytest.mark.parametrize("name", SHIPPED)
def test_the_time_series_show_every_drive_one_unit_per_axis_and_no_legend_on_data(
        name: str) -> None:
    """The figure of each shipped scenario (drawn once, from made-up runs): every drive of
    every variant (franchetti2021: the anchor drive of the active_relocation variants beside
    the link drive of all; demian2022: q1 and q2), every line inside its axes, one unit per
    axis, every legend beside the axes."""
    fig = drawn(name)
    scenario = scenario_files.load(name)
    assert len(plots.drives(scenario)) == {"franchetti2021": 2, "ciupitu2018": 1,
                                           "demian2022": 2}[name]
    assert_every_drive_of_every_variant_is_drawn(fig, scenario)
    assert_every_line_lies_inside_its_axes(fig)
    assert_each_axis_carries_one_unit(fig)
    assert_no_legend_covers_data(fig)


@pytest.mark.parametrize("name", SHIPPED)
def test_titles_cite_the_scenarios_source(name: str) -> None:
    """Each shipped scenario names its paper (its file's name is the first author and year),
    every figure's title cites it and no other scenario's paper, and the realistic set's
    title says so."""
    scenario = scenario_files.load(name)
    words = scenario.source.split()
    assert name == f"{words[0].lower()}{words[-1]}", scenario.source
    others = {scenario_files.load(n).source for n in SHIPPED} - {scenario.source}
    realistic_set = dict(losses.loss_sets(scenario, "realistic"))["realistic"]
    realistic = plots.figure(made_up_runs(realistic_set), realistic_set,
                             "realistic").get_suptitle()
    time_series = plots.figure(made_up_runs(scenario), scenario).get_suptitle()
    energy = plots.energy_figure(scenario, {}).get_suptitle()
    for title in (time_series, energy, realistic):
        assert title.startswith(name) and title.endswith(f"({scenario.source})"), title
        assert not any(other.split()[0] in title for other in others), title
    assert "realistic losses" in realistic


@pytest.mark.parametrize("name", SHIPPED)
def test_the_headline_shows_every_variant_in_both_loss_sets_on_a_log_axis(name: str) -> None:
    """A bar per variant and loss set ending at its E_drawn, its value printed beside it
    inside the axes; the smallest (self_regulating's 0.07 J beside 126 J) is still at least
    a tenth of the axes wide, which no linear axis gives."""
    fig, tables = headline(name)
    (ax,) = fig.axes
    scenario = scenario_files.load(name)
    assert ax.get_xscale() == "log"
    labels = [t.get_text().removesuffix(" (baseline)") for t in ax.get_yticklabels()]
    assert labels == list(scenario.variants)
    bars = [p for p in ax.patches if isinstance(p, Rectangle)]
    ends = sorted(bar.get_x() + bar.get_width() for bar in bars)
    energies = sorted(e for table in tables.values() for e in table.E_drawn)
    assert len(bars) == 2 * len(scenario.variants)
    np.testing.assert_allclose(ends, energies, rtol=1e-12)
    texts = {t.get_text() for t in ax.texts}
    assert texts == {f"{plots.significant(e)} J" for e in energies}
    (x0, x1), area = ax.get_xlim(), ax.get_window_extent()
    for bar in bars:
        assert x0 <= bar.get_x() and bar.get_x() + bar.get_width() <= x1
        assert bar.get_window_extent().width >= 0.1 * area.width
    for text in ax.texts:
        box = text.get_window_extent()
        assert area.x0 <= box.x0 and box.x1 <= area.x1 and area.y0 <= box.y0 <= box.y1 <= area.y1
    assert re.fullmatch(r".*\[J\].*", ax.get_xlabel())
    assert_no_legend_covers_data(fig)


def test_a_loss_set_without_a_variant_says_not_run() -> None:
    """A variant one summary lacks, or whose E_drawn is not positive, has no bar: its text
    says so."""
    scenario = scenario_files.load("demian2022")
    table = pd.DataFrame({"variant": ["compensated", "uncompensated"], "E_drawn": [0.0, 20.0]})
    fig = plots.energy_figure(scenario, {"ideal": table})
    (ax,) = fig.axes
    assert sorted(t.get_text() for t in ax.texts) == ["0 J", "20.0 J", "not run"]
    assert len(ax.patches) == 1


def test_the_headline_is_drawn_from_every_loss_set_written(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """write_energy_figure draws <scenario>_energy.png in the scenario's folder from each
    loss set's summary there is: the realistic set written first gives a figure of it alone,
    the ideal one after of both; it waits for the folder's lock."""
    scenario = scenario_files.load("demian2022")
    folders = losses.set_folders(tmp_path / "demian2022")
    drawn_from = []
    monkeypatch.setattr(plots, "energy_figure", lambda _, tables: drawn_from.append(
        {s: list(t.E_drawn) for s, t in tables.items()}) or Figure())
    for loss_set, energy in (("realistic", 2.0), ("ideal", 1.0)):
        folders[loss_set].mkdir(parents=True, exist_ok=True)
        pd.DataFrame({"variant": ["compensated"], "E_drawn": [energy], "model": "M"}).to_csv(
            folders[loss_set] / "summary.csv", index=False)
        path = results.write_energy_figure(scenario, folders)
    assert path == tmp_path / "demian2022" / "demian2022_energy.png" and path.exists()
    assert drawn_from == [{"realistic": [2.0]}, {"ideal": [1.0], "realistic": [2.0]}]
    writer = threading.Thread(target=results.write_energy_figure, args=(scenario, folders))
    with results.locked(folders["ideal"]):
        writer.start()
        time.sleep(0.3)
        assert len(drawn_from) == 2
    writer.join(5.0)
    assert len(drawn_from) == 3
