"""Parameter sweeps (harness.sweeps): configuration paths, plans, equality with runs made one
by one, failed runs and defects, a sweep killed half way and restarted, and the plots drawn
from a result table of known numbers."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from matplotlib.axes import Axes

from harness import scenarios
from harness import sweeps as sweep
from harness.drive.controller import ControllerDesign
from harness.engines import fmpy_master
from harness.engines.plan import prepare
from harness.errors import UserError
from harness.scenarios import Ramp
from harness.sweeps import definition, execution, paths, plots

DATA = Path(__file__).resolve().parent / "data"
SMALL = DATA / "sweep_small.toml"    # 2 payloads x k in (981, -1) x 2 variants
RESUME = DATA / "sweep_resume.toml"  # 12 regulation angles, one run per chunk
FRANCHETTI = scenarios.load("franchetti2021")


def test_configure_sets_paths_without_touching_the_scenario() -> None:
    scenario, motor, design = paths.configure(FRANCHETTI, [
        ('phases["III regulate"].inputs.payload', 3.0),
        ('phases["II move", "III regulate", "IV settle and lock"].target_deg', 150.0),
        ("parameters.L0", 0.02), ("motor.N", 80.0), ("duration_scale", 0.5)])
    phases = {p.name: p for p in scenario.phases}
    assert phases["III regulate"].inputs["payload"] == Ramp(3.0)
    assert phases["III regulate"].inputs["counterweight_added"] == Ramp(1.0)
    assert [math.degrees(p.target[0]) for p in scenario.phases] == pytest.approx(
        [60.0, 150.0, 150.0, 150.0, 340.0, 340.0])
    assert scenario.duration == pytest.approx(17.5)
    assert scenario.parameters["L0"] == 0.02 and motor.N == 80.0
    assert design == ControllerDesign()
    # the loaded scenario is unchanged
    assert FRANCHETTI.duration == 35.0 and "L0" not in FRANCHETTI.parameters
    assert FRANCHETTI.phases[2].inputs["payload"] == Ramp(1.0)


def test_a_factor_scales_the_value_and_variant_paths_reach_its_joints() -> None:
    """regulation.toml's payload axis: the payload ramps (the scenario's and
    active_relocation's own quintic) and the anchor's travel, 58.3 mm per kg."""
    loaded = definition.load("regulation")
    assert len(definition.plan(loaded)) == 84
    assert loaded.outputs == ("E_cw", "W_adjust", "E_e", "balance_error")
    scenario, _, _ = paths.configure(FRANCHETTI, definition.assignments(
        loaded, {"payload": 3.0, "regulation_angle": 90.0}))
    variant = scenario.variant("active_relocation")
    assert variant.phase_inputs["III regulate"]["payload"] == Ramp(3.0, "quintic")
    assert variant.phase_targets["III regulate"]["q"] == pytest.approx(
        3.0 * 0.35 * 9.81 / (981.0 * 0.06), rel=1e-12)
    resolved = scenario.for_variant(variant)
    assert resolved.reference_at(17.0) == pytest.approx((math.pi / 2, 0.175), rel=1e-12)
    assert FRANCHETTI.variant("active_relocation").phase_targets["III regulate"]["q"] == (
        pytest.approx(0.0583333, rel=1e-6))
    with pytest.raises(paths.PathError, match="'two' is not a number"):
        paths.configure(FRANCHETTI, [("two * parameters.k", 1.0)])


@pytest.mark.parametrize("path", ['phases["III regulte"].target_deg', "parameters.L0.x",
                                  "motor.Nx", 'phases["I hold"].inputs[1]', "phases.target"])
def test_configure_rejects_bad_paths(path: str) -> None:
    with pytest.raises(paths.PathError, match="set path"):
        paths.configure(FRANCHETTI, [(path, 1.0)])
    with pytest.raises(paths.PathError, match="set path"):  # checked without a value
        paths.configure(FRANCHETTI, [(path, None)])


def test_bad_values_and_bad_paths_stop_the_sweep_refused_runs_fail(tmp_path: Path) -> None:
    """A value out of its field's range (motor.N = -1) stops the sweep at load, naming the
    axis, the value and the field, before any run is spent on it. A run whose
    configuration is refused all the same (values refused only together) is a failed row."""
    path = tmp_path / "motor.toml"
    text = (SMALL.read_text().replace('"short_regulation.toml"',
                                      f"'{DATA / 'short_regulation.toml'}'")
            .replace('"parameters.k"', '"motor.N"').replace("[981.0, -1.0]", "[-1.0, 80.0]"))
    path.write_text(text)
    with pytest.raises(UserError, match=r"axis k value -1: set path 'motor.N': N = -1.0 1 is "
                                        r"outside \(0.0, inf\)"):
        definition.load(path)
    path.write_text(text.replace("[-1.0, 80.0]", "[80.0, 90.0]"))
    loaded = definition.load(path)
    first = definition.plan(loaded)[0]
    row = execution.run_one(loaded, replace(first, values={**first.values, "k": -1.0}))
    assert row["status"] == "failed"
    assert row["error"].startswith("RefusedValueError: set path 'motor.N': ")
    assert "N = -1.0" in row["error"]
    path.write_text(text.replace('"motor.N"', '"motor.n"'))
    with pytest.raises(paths.PathError, match="MotorParameters has no 'n'"):
        definition.load(path)


def test_latin_hypercube_plan_is_stratified_and_stable(tmp_path: Path) -> None:
    path = tmp_path / "lhs.toml"
    path.write_text(SMALL.read_text().replace('chunk_size = 3', 'sample = "lhs"\nsamples = 10')
                    .replace("values = [0.5, 1.5]", "range = { start = 0.0, stop = 10.0 }")
                    .replace('"short_regulation.toml"', f"'{DATA / 'short_regulation.toml'}'"))
    loaded = definition.load(path)
    runs = definition.plan(loaded)
    assert len(runs) == 20 and len({r.run_id for r in runs}) == 20
    payloads = sorted(r.values["payload"] for r in runs[::2])
    assert [math.floor(p) for p in payloads] == list(range(10))  # one per stratum
    assert {r.values["k"] for r in runs} <= {981.0, -1.0}
    assert [r.run_id for r in definition.plan(definition.load(path))] == [r.run_id for r in runs]


def by_hand(payload: float, k: float) -> scenarios.Scenario:
    """The short scenario with a payload and stiffness, built without harness.sweeps."""
    base = scenarios.load(DATA / "short_regulation.toml")
    phases = tuple(replace(p, inputs={**p.inputs, "payload": Ramp(payload),
                                      "counterweight_added": Ramp(payload)})
                   if p.name == "regulate" else p for p in base.phases)
    return replace(base, parameters={**base.parameters, "k": k}, phases=phases)


@pytest.mark.slow   # about 10 s: a sweep and each of its runs again
def test_sweep_equals_runs_one_by_one_and_records_failures(tmp_path: Path) -> None:
    loaded = definition.load(SMALL)
    table = sweep.run_sweep(SMALL, tmp_path, workers=2, quiet=True)
    assert list(table.run_id) == [r.run_id for r in definition.plan(loaded)]
    assert pd.read_parquet(tmp_path / "small.parquet").equals(table)
    written = pd.read_csv(tmp_path / "small.csv")
    assert list(written.columns) == list(table.columns)
    assert list(written.run_id) == list(table.run_id)
    assert list(written.status) == list(table.status) == ["ok", "ok", "failed", "failed"] * 2
    for metric in (*loaded.metrics, "payload", "k"):  # the CSV keeps 10 significant digits
        assert written[metric].to_numpy() == pytest.approx(table[metric].to_numpy(), rel=1e-9,
                                                           nan_ok=True), metric
    for row in table.itertuples():
        scenario = by_hand(row.payload, row.k)
        if row.k < 0.0:  # bad parameter: recorded, with the FMU's message
            assert row.status == "failed"
            assert "k = -1.0 N/m is outside [0.0, inf)" in row.error
            with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
                fmpy_master.run(prepare(scenario, scenario.variant(row.variant)))
            continue
        assert row.status == "ok" and row.error == ""
        expected = fmpy_master.run(prepare(scenario, scenario.variant(row.variant))).metrics
        for metric in loaded.metrics:
            assert getattr(row, metric) == expected[metric], (row.run_id, metric)
        assert row.payload_max == pytest.approx(8.2857, abs=1e-4)


@pytest.mark.slow  # about 9 s: a sweep killed and resumed in subprocesses
def test_killed_sweep_resumes_without_losing_or_repeating_runs(tmp_path: Path) -> None:
    loaded = definition.load(RESUME)
    parts = execution.parts_dir(loaded, tmp_path)
    command = [sys.executable, "-m", "harness", "sweep", str(RESUME), "--out", str(tmp_path),
               "--workers", "1", "--quiet"]
    process = subprocess.Popen(command, start_new_session=True, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60.0
        while len(list(parts.glob("part-*.parquet"))) < 3:
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.02)
    finally:  # the sweep, its scheduler and worker processes: one process group
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    before = execution.stored(loaded, tmp_path)
    assert 3 <= len(before) < 12
    assert not (tmp_path / "resume.parquet").exists()

    table = sweep.run_sweep(RESUME, tmp_path, workers=2, quiet=True)
    planned = [r.run_id for r in definition.plan(loaded)]
    assert list(table.run_id) == planned and (table.status == "ok").all()
    stored_rows = pd.concat([pd.read_parquet(p) for p in parts.glob("part-*.parquet")])
    assert sorted(stored_rows.run_id) == sorted(planned)  # nothing computed twice
    kept = table.set_index("run_id").loc[before.run_id]
    assert list(kept.seconds) == list(before.seconds)  # the first session's rows, unchanged
    assert execution.pending(loaded, tmp_path) == []


def test_a_defect_in_a_run_propagates_but_a_refused_value_is_a_failed_row(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Only a UserError (a value the configuration or the FMU refuses) becomes a failed
    row; any other exception is a defect of the harness and must not be hidden in a row."""
    loaded = definition.load(SMALL)
    run = definition.plan(loaded)[0]
    monkeypatch.setattr(execution, "model_instance", lambda model: SimpleNamespace(messages=[]))

    def defect(*_args: object, **_kwargs: object) -> None:
        raise TypeError("a bug")

    monkeypatch.setattr(fmpy_master, "run", defect)
    with pytest.raises(TypeError, match="a bug"):
        execution.run_one(loaded, run)

    def refused(*_args: object, **_kwargs: object) -> None:
        raise UserError("k = -1.0 N/m is outside [0.0, inf)")

    monkeypatch.setattr(fmpy_master, "run", refused)
    row = execution.run_one(loaded, run)
    assert row["status"] == "failed"
    assert row["error"] == "UserError: k = -1.0 N/m is outside [0.0, inf)"


# ---- plots: drawn from a made-up result table of known numbers
PLOTTED = '''
name = "plotted"
scenario = "SCENARIO"
variants = ["self_regulating", "unregulated"]
metrics = ["E_drawn"]
[[axes]]
name = "payload"
unit = "kg"
set = ['phases["regulate"].inputs.payload']
values = [0.5, 1.5, 2.5]
[[axes]]
name = "k"
unit = "N/m"
set = ["parameters.k"]
values = [981.0, 500.0]
[plots.saving]
x = "payload"
lines = "k"
mark = "payload_max"
variant = "unregulated"
baseline = "self_regulating"
[plots.map]
x = "payload"
y = "k"
[plots.lines]
x = "payload"
lines = "k"
y = ["E_drawn"]
'''


def drawn(variant: str, payload: float, k: float) -> float:
    """The made-up E_drawn [J]: self_regulating grows with k, unregulated with the payload."""
    return 1.0 + k / 1000.0 if variant == "self_regulating" else 1.0 + payload


@pytest.fixture(scope="module")
def plotted(tmp_path_factory: pytest.TempPathFactory) -> tuple[definition.Sweep, pd.DataFrame]:
    """The sweep file above and its result table, the run at payload 2.5, k 500 and
    variant unregulated failed."""
    path = tmp_path_factory.mktemp("plotted") / "plotted.toml"
    path.write_text(PLOTTED.replace("SCENARIO", str(DATA / "short_regulation.toml")))
    loaded = definition.load(path)
    rows = [{"point": r.point, "variant": r.variant, **r.values, "status": "ok",
             "E_drawn": drawn(r.variant, **r.values), "payload_max": 2.0}
            for r in definition.plan(loaded)]
    rows[-1].update(status="failed", E_drawn=math.nan)
    return loaded, pd.DataFrame(rows)


def lines_of(ax: Axes) -> dict[str, tuple[list[float], list[float]]]:
    """The labelled lines of a panel: label -> (x data, y data)."""
    return {line.get_label(): (list(line.get_xdata()), list(line.get_ydata()))
            for line in ax.get_lines() if not line.get_label().startswith("_")}


def test_every_plot_kind_of_a_sweep_file_has_a_figure() -> None:
    assert tuple(plots.FIGURES) == definition.PLOT_KINDS


def test_saving_compares_the_variants_the_sweep_file_names(
        plotted: tuple[definition.Sweep, pd.DataFrame]) -> None:
    loaded, table = plotted
    assert loaded.plots["map"] | {} == {"x": "payload", "y": "k", "variant": "self_regulating",
                                        "baseline": "unregulated"}  # the default: first two
    fig = plots.saving_figure(loaded, table, loaded.plots["saving"])
    top, bottom = fig.axes[:2]
    # top: 100 (1 - E_drawn(unregulated) / E_drawn(self_regulating)) per k, against payload
    expected = {k: [100.0 * (1.0 - (1.0 + p) / (1.0 + k / 1000.0)) for p in (0.5, 1.5, 2.5)]
                for k in (500.0, 981.0)}
    shown = lines_of(top)
    assert set(shown) == {"k [N/m] = 500", "k [N/m] = 981"}
    assert shown["k [N/m] = 981"][0] == [0.5, 1.5, 2.5]
    assert shown["k [N/m] = 981"][1] == pytest.approx(expected[981.0])
    assert shown["k [N/m] = 500"][1][:2] == pytest.approx(expected[500.0][:2])
    assert math.isnan(shown["k [N/m] = 500"][1][2])  # the failed run
    assert top.get_ylabel() == "energy saving [%]"
    assert ("saving = 1 - E_drawn(unregulated) / E_drawn(self_regulating)"
            in " ".join(fig.get_suptitle().split()))
    # the mark: a vertical line at payload_max
    assert any(list(line.get_xdata()) == [2.0, 2.0] for line in top.get_lines())
    # bottom: E_drawn of both variants (solid the variant, dashed the baseline), log scale
    assert bottom.get_yscale() == "log" and bottom.get_xlabel() == "payload [kg]"
    curves = [(line.get_linestyle(), list(line.get_ydata())) for line in bottom.get_lines()
              if len(line.get_xdata())]
    assert curves[:4] == [("-", pytest.approx([1.5, 2.5, math.nan], nan_ok=True)),  # k = 500
                          ("--", pytest.approx([1.5] * 3)),
                          ("-", pytest.approx([1.5, 2.5, 3.5])),
                          ("--", pytest.approx([1.981] * 3))]
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [
        "k [N/m] = 500", "k [N/m] = 981", "E_drawn of unregulated",
        "E_drawn of self_regulating"]  # under the panels, over no data
    assert "unregulated against self_regulating" in " ".join(fig.get_suptitle().split())


def test_map_shows_the_saving_of_each_point(
        plotted: tuple[definition.Sweep, pd.DataFrame]) -> None:
    loaded, table = plotted
    fig = plots.map_figure(loaded, table, loaded.plots["map"])
    ax = fig.axes[0]
    # rows k (500, 981), columns payload; the failed run's cell empty
    cells = np.ma.filled(ax.collections[0].get_array(), np.nan).reshape(2, 3)
    expected = [[100.0 * (1.0 - (1.0 + k / 1000.0) / (1.0 + p)) for p in (0.5, 1.5, 2.5)]
                for k in (500.0, 981.0)]
    assert list(cells[0]) == pytest.approx([*expected[0][:2], math.nan], nan_ok=True)
    assert list(cells[1]) == pytest.approx(expected[1])
    assert [t.get_text() for t in ax.texts] == [f"{v:.0f}" for v in
                                                (*expected[0][:2], *expected[1])]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0.5", "1.5", "2.5"]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("payload [kg]", "k [N/m]")


def test_lines_draw_each_column_per_variant(
        plotted: tuple[definition.Sweep, pd.DataFrame]) -> None:
    loaded, table = plotted
    fig = plots.lines_figure(loaded, table, loaded.plots["lines"])
    for ax, variant in zip(fig.axes, loaded.variants, strict=True):
        assert ax.get_title() == variant and ax.get_ylabel() == "E_drawn"
        for k in (500.0, 981.0):
            x, y = lines_of(ax)[f"k [N/m] = {k:g}"]
            ok = [p for p in (0.5, 1.5, 2.5) if variant != "unregulated" or (p, k) != (2.5, 500.0)]
            assert x == ok and y == pytest.approx([drawn(variant, p, k) for p in ok])


def test_a_value_of_the_lines_axis_may_have_a_name(
        plotted: tuple[definition.Sweep, pd.DataFrame]) -> None:
    """`lines_labels` names values of the lines axis (design_rule's paper_design 0 and 1)
    in the legend; a value it does not name reads '<axis> = <value>'."""
    loaded, table = plotted
    spec = {**loaded.plots["saving"], "lines_labels": {"500": "soft spring"}}
    fig = plots.saving_figure(loaded, table, spec)
    assert [t.get_text() for t in fig.legends[0].get_texts()][:2] == [
        "soft spring", "k [N/m] = 981"]


def test_lines_draw_no_panel_for_a_column_a_variant_lacks() -> None:
    """regulation's lines: the columns both variants have share the bottom rows, each
    variant's own stand above them; no empty panel."""
    rows, row_of = plots.lines_layout(
        ["E_cw", "W_adjust", "E_drawn_q", "E_drawn", "balance_error"],
        {"self_regulating": ["E_cw", "E_drawn", "balance_error"],
         "active_relocation": ["W_adjust", "E_drawn_q", "E_drawn", "balance_error"]})
    assert rows == 4
    assert row_of == {("self_regulating", "E_cw"): 1, ("active_relocation", "W_adjust"): 0,
                      ("active_relocation", "E_drawn_q"): 1,
                      ("self_regulating", "E_drawn"): 2, ("active_relocation", "E_drawn"): 2,
                      ("self_regulating", "balance_error"): 3,
                      ("active_relocation", "balance_error"): 3}


def test_plot_writes_one_png_per_plot_of_the_file(
        plotted: tuple[definition.Sweep, pd.DataFrame], tmp_path: Path) -> None:
    loaded, table = plotted
    written = plots.plot(loaded, table, tmp_path)
    assert written == [tmp_path / f"plotted_{kind}.png" for kind in ("saving", "map", "lines")]
    assert all(p.read_bytes().startswith(b"\x89PNG\r\n\x1a\n") for p in written)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in written)


def test_a_sweep_is_refused_over_a_table_of_runs_it_does_not_plan(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The committed sweeps' tables are their files' plans; the table1 file with its first
    axis's values changed, into results/sweeps, is refused in one line naming --out and
    --replace before anything runs (and accepted with replace)."""
    for name in ("table1", "regulation", "design_rule", "real_spring", "slider_friction"):
        sweep.check_table(definition.load(name), sweep.SWEEP_RESULTS_DIR)
    table1 = definition.load("table1")
    first = table1.axes[0]
    edited = replace(table1, axes=(replace(first, values=tuple(v * 1.5 for v in first.values)),
                                   *table1.axes[1:]))
    with pytest.raises(UserError, match=r"table1.parquet holds a sweep made with other "
                       r"settings \(\d+ of its 264 rows are not in table1's plan\): write to "
                       "another --out, or add --replace"):
        sweep.check_table(edited, sweep.SWEEP_RESULTS_DIR)
    sweep.check_table(edited, sweep.SWEEP_RESULTS_DIR, replace=True)
