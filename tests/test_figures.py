"""Every figure reads: the checks of tests/figure_checks.py on every committed PNG's producer
(drawn from the committed tables, harness.report.figures, no co-simulation) and on compare's
plot, each check against a figure made with its defect (which it must flag) and the same
figure made right (which it must pass), and the drawing helpers of harness.run.plots."""

from __future__ import annotations

import math
from pathlib import Path

import figure_checks as checks
import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from harness.report import figures
from harness.run import compare, plots
from harness.run.results import RESULTS_DIR
from harness.study import plots as study_plots

COMMITTED = figures.committed()


def test_every_committed_png_has_a_producer() -> None:
    """Each PNG under results/ is drawn by a producer the checks below run, and each
    producer draws a committed PNG (a new figure gets checked, or its PNG is stale)."""
    assert set(RESULTS_DIR.rglob("*.png")) == set(COMMITTED)


@pytest.mark.parametrize("path", sorted(COMMITTED), ids=lambda p: str(p.relative_to(RESULTS_DIR)))
def test_every_committed_figure_passes_every_check(path: Path) -> None:
    fig = COMMITTED[path]()
    assert fig is not None
    assert checks.defects(fig) == []


def test_redraw_writes_the_figures_named_from_the_tables_alone(tmp_path: Path) -> None:
    """redraw draws ecco.png from a copy of the committed ecco.csv, which it leaves as it
    was; a PNG no table gives is refused."""
    (tmp_path / "bench").mkdir()
    table = tmp_path / "bench" / "ecco.csv"
    table.write_bytes((RESULTS_DIR / "bench" / "ecco.csv").read_bytes())
    assert list(figures.committed(tmp_path)) == [tmp_path / "bench" / "ecco.png"]
    assert figures.redraw([tmp_path / "bench" / "ecco.png"], tmp_path) == [
        tmp_path / "bench" / "ecco.png"]
    assert (tmp_path / "bench" / "ecco.png").read_bytes().startswith(b"\x89PNG")
    assert table.read_bytes() == (RESULTS_DIR / "bench" / "ecco.csv").read_bytes()
    with pytest.raises(KeyError, match="no committed figure"):
        figures.redraw([tmp_path / "bench" / "other.png"], tmp_path)


def test_compare_plot_passes_every_check() -> None:
    """compare --plot on two committed result files (ideal against realistic: some signals
    fail): a difference panel per signal, a unit on every y axis."""
    reference = compare.read_result(RESULTS_DIR / "franchetti2021" / "self_regulating.csv")
    result = compare.read_result(RESULTS_DIR / "franchetti2021" / "realistic"
                                 / "self_regulating.csv")
    fig = compare.figure(reference, result, compare.compare(reference, result,
                                                            ["theta", "tau_drive", "E_drawn"]))
    assert checks.defects(fig) == []
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["theta [rad]", "difference [rad]", "tau_drive [N m]",
                      "difference [N m]", "E_drawn [J]", "difference [J]"]


# ---- negative controls: each check flags its defect, and passes the figure made right

def panel(width: float = 4.0, height: float = 3.0, layout: str | None = "constrained"
          ) -> tuple[Figure, object]:
    fig = Figure(figsize=(width, height), layout=layout)
    return fig, fig.subplots()


def labelled(ax: object, x: str = "time [s]", y: str = "length [mm]") -> None:
    ax.set_xlabel(x)
    ax.set_ylabel(y)


def test_a_text_leaving_the_figure_is_flagged() -> None:
    fig, ax = panel(layout=None)
    ax.plot([0, 1], [0, 1])
    labelled(ax)
    fig.suptitle("a title far too long for a figure four inches wide, cut on both sides")
    assert any("leaves the figure" in f for f in checks.texts_outside(fig))
    fig, ax = panel()
    ax.plot([0, 1], [0, 1])
    labelled(ax)
    plots.fit_suptitle(fig, "a title far too long for a figure four inches wide, now wrapped")
    assert checks.texts_outside(fig) == []


def test_overlapping_texts_are_flagged() -> None:
    """A y label longer than the panel runs into the title (the sweeps' saving figure); two
    line-end labels at one height overlap (the study's dependence figure)."""
    fig, ax = panel(5.0, 2.0, layout=None)
    ax.plot([0, 1], [0, 1])
    labelled(ax, y="saving 1 - E_drawn(self_regulating) / E_drawn(unregulated) [%]")
    fig.suptitle("slider_friction: drive energy saved by self_regulating against unregulated")
    assert any("overlaps" in f for f in checks.overlapping_texts(fig))
    fig, ax = panel()
    ax.plot([0, 1], [1.0, 1.0], [0, 1], [1.01, 1.01])
    ax.set_ylim(0.0, 2.0)
    for name, y in (("parabolic_balanced", 1.0), ("parabolic_unbalanced", 1.01)):
        ax.annotate(name, (1, y), xytext=(6, 0), textcoords="offset points")
    assert any("overlaps" in f for f in checks.overlapping_texts(fig))
    fig, ax = panel(5.0, 3.0)
    ax.plot([0, 1], [0, 1])
    labelled(ax, y="energy saving [%]")
    fig.suptitle("title")
    assert checks.overlapping_texts(fig) == []


@pytest.mark.parametrize("data", ["line", "bars", "scatter"])
def test_a_legend_over_data_is_flagged(data: str) -> None:
    fig, ax = panel()
    x = np.linspace(0.0, 1.0, 5)  # few points: the segments, not only the points, count
    {"line": lambda: ax.plot(x, 0.5 + 0 * x, label="a"),
     "bars": lambda: ax.bar(x, 0.5 + 0 * x, 0.2, label="a"),
     "scatter": lambda: ax.scatter([0.5], [0.5], label="a")}[data]()
    ax.set_ylim(0.0, 1.0)
    labelled(ax)
    ax.legend(loc="center")
    assert checks.legend_over_data(fig)
    ax.get_legend().remove()
    fig.legend(loc="outside lower center")
    checks._DRAWN.discard(fig)  # changed after its first check: laid out again
    assert checks.legend_over_data(fig) == []


def test_a_log_axis_of_two_labelled_ticks_is_flagged() -> None:
    """matplotlib's own labels over 1.3 decades are two (the bench's ecco.png); readable_log
    labels at least three."""
    fig, ax = panel()
    ax.semilogy([0, 1], [10.0, 200.0])
    labelled(ax)
    assert any("fewer than 3" in f for f in checks.sparse_log_axes(fig))
    fig, ax = panel()
    ax.semilogy([0, 1], [10.0, 200.0])
    plots.readable_log(ax.yaxis)
    labelled(ax)
    assert checks.sparse_log_axes(fig) == []


def test_a_bar_cut_by_or_ending_at_the_axis_limit_is_flagged() -> None:
    """A range bar from 0.097 on an axis from 0.1 is cut; one from the axis's first value
    (matplotlib's sticky edge) cannot be told from a cut one; bars from a common base are
    whole."""
    for limits in ((0.1, 100.0), None):
        fig, ax = panel()
        ax.set_xscale("log")
        ax.barh([0, 1], [17.3, 30.0], left=[0.097, 1.0])
        if limits:
            ax.set_xlim(*limits)
        labelled(ax, x="E_drawn [J]", y="")
        assert checks.cut_bars(fig), limits
    fig, ax = panel()
    ax.set_xscale("log")
    ax.barh([0, 1], [17.3, 30.0], left=[0.097, 1.0])
    ax.set_xlim(0.097 / 1.3, 31.0 * 1.3)
    assert checks.cut_bars(fig) == []
    fig, ax = panel()
    ax.bar([0, 1], [3.0, 5.0])  # from the axis at 0, their common base
    assert checks.cut_bars(fig) == []


def test_an_empty_panel_is_flagged() -> None:
    fig = Figure(layout="constrained")
    full, empty = fig.subplots(1, 2)
    full.plot([0, 1], [0, 1])
    empty.text(0.5, 0.5, "no E_cw", transform=empty.transAxes)
    assert [f.split(": ", 1)[1] for f in checks.empty_axes(fig)] == [
        "an empty panel saying ['no E_cw']"]
    empty.set_visible(False)
    assert checks.empty_axes(fig) == []


@pytest.mark.parametrize("label", ["", "mm | kg", "length [mm] and mass [kg]", "mm",
                                   "position [mm, kg]"])
def test_an_axis_without_one_unit_is_flagged(label: str) -> None:
    fig, ax = panel()
    ax.plot([0, 1], [0, 1])
    labelled(ax, y=label)
    assert checks.axes_without_one_unit(fig)


def test_an_axis_of_one_unit_or_of_categories_passes() -> None:
    fig, ax = panel()
    ax.barh([0, 1], [1.0, 2.0])
    ax.set_yticks([0, 1], ["self_regulating", "unbalanced"])  # categories: no unit
    ax.set_xlabel("E_drawn / E_drawn(self_regulating) [-] (log scale)")
    assert checks.axes_without_one_unit(fig) == []


def test_values_of_mixed_significant_figures_are_flagged() -> None:
    """'13 J' beside '8.92 J' (the study's energy figure); with plots.significant both have
    three figures; cells of one decimal count ('96', '100') pass."""
    texts = {"mixed": ["13 J", "8.92 J", "0.159 J"],
             "three figures": [f"{plots.significant(v)} J" for v in (13.0, 8.92, 0.159)],
             "whole percents": ["96", "100", "-794", "5"]}
    found = {}
    for name, values in texts.items():
        fig, ax = panel()
        ax.plot([0, 1], [0, 1])
        labelled(ax)
        for k, value in enumerate(values):
            ax.text(0.1, 0.2 + 0.2 * k, value)
        found[name] = checks.mixed_figures(fig)
    assert found["mixed"] and not found["three figures"] and not found["whole percents"]


def test_a_line_hidden_under_another_is_flagged() -> None:
    """Two variants' equal lines (demian2022's compensated under compensated_backdrivable
    in every q1 panel): the first is hidden; show_coinciding gives both markers in sight."""
    x = np.linspace(0.0, 8.0, 400)
    fig, ax = panel()
    lines = [*ax.plot(x, np.sin(x), color="C0", label="compensated"),
             *ax.plot(x, np.sin(x), color="C1", label="compensated_backdrivable"),
             *ax.plot(x, np.cos(x), color="C2", label="uncompensated")]
    labelled(ax)
    assert [f.split(": ", 1)[1] for f in checks.hidden_lines(fig)] == [
        "'compensated' (colour #1f77b4) lies hidden under 'compensated_backdrivable'"]
    fig, ax = panel()
    lines = [*ax.plot(x, np.sin(x), color="C0"), *ax.plot(x, np.sin(x), color="C1"),
             *ax.plot(x, np.cos(x), color="C2")]
    assert plots.show_coinciding(lines)
    assert [line.get_marker() for line in lines] == ["o", "s", "None"]
    assert checks.hidden_lines(fig) == []


# ---- the helpers every figure draws with

@pytest.mark.parametrize(("value", "text"), [(13.0, "13.0"), (0.0747, "0.0747"),
                                             (1234.0, "1230"), (99.96, "100"), (20.0, "20.0"),
                                             (-4.5678, "-4.57"), (0.0, "0")])
def test_significant_prints_three_figures(value: float, text: str) -> None:
    assert plots.significant(value) == text


@pytest.mark.parametrize(("low", "high"), [(0.097, 140.0), (2.4, 80.0), (0.7, 3.0),
                                           (1.5, 2.9), (1e-4, 6e-3), (1900.0, 70000.0),
                                           (1.01, 1.05)])
def test_log_ticks_put_three_ticks_in_any_view(low: float, high: float) -> None:
    ticks = plots.LogTicks().tick_values(low, high)
    assert len(ticks) >= 3 and all(low <= t <= high for t in ticks), ticks


def test_the_time_series_draws_decades_of_energy_on_a_log_axis_and_letters_its_panels() -> None:
    """franchetti2021: self-regulation's 0.07 J beside the unbalanced 20 J on a symmetric
    log axis; the mechanism's panels (a) link angle to (e) spring length or counterweight
    position, Franchetti's Fig. 5 (a)-(d) with his (c) in two, then the drives' (f) on."""
    fig = COMMITTED[RESULTS_DIR / "franchetti2021" / "franchetti2021.png"]()
    titles = [ax.get_title(loc="left") for ax in fig.axes if ax.get_visible()]
    assert [t for t in titles if t[1] in "abcde"] == [
        "(a) link angle", "(b) energies", "(c) adjuster travel", "(d) payload",
        "(e) spring length or counterweight position"]
    assert sorted(t[1] for t in titles) == list("abcdefghijklmno")
    energy = next(ax for ax in fig.axes if ax.get_title(loc="left").endswith(
        "drive theta: energy drawn"))
    assert energy.get_yscale() == "symlog"
    self_regulating = energy.get_lines()[0]  # the scenario's first variant
    assert self_regulating.get_ydata()[-1] == pytest.approx(0.0747, abs=5e-4)


def test_a_study_of_few_tasks_does_not_say_quartiles() -> None:
    """The dependence title names the bins the table has: 4 of 50 tasks are quartiles, 2
    bins of 1 and 2 tasks (a 3-task study) are not."""
    table = pd.DataFrame({"losses": "ideal", "axis": "hold_fraction",
                          "low": [0.0, 0.0, 0.5, 0.5], "high": [0.5, 0.5, 1.0, 1.0],
                          "tasks": [1, 1, 2, 2], "variant": ["a", "b"] * 2,
                          "ratio_median": [1.0, 2.0, 1.0, 3.0], "least_fraction": 0.5})
    fig = study_plots.dependence_figure("s", table, "a")
    assert "quartiles" not in fig.get_suptitle()
    assert "2 bins of 1 to 2 tasks" in " ".join(fig.get_suptitle().split())
    assert checks.defects(fig) == []
    four = pd.concat([table.assign(low=table.low + k, high=table.high + k, tasks=50)
                      for k in (0, 2)], ignore_index=True)
    assert "quartiles of the tasks (50 tasks each)" in " ".join(
        study_plots.dependence_figure("s", four, "a").get_suptitle().split())


def test_not_a_number_keeps_its_text() -> None:
    assert plots.significant(math.nan) == "nan" and plots.significant(math.inf) == "inf"
