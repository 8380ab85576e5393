"""Power bonds (docs/results.md#power-bonds): the coupling's energy per drive-to-joint bond in
every run, and libcosim's ECCO algorithm on the systems of harness.engines.libcosim.

The bond's two sides are integrals of the same effort against two speeds: the drive's
(tau omega_held h) and the joint's (tau_held dq). With the harness's master the effort is the
same on both sides, so the error is sum tau_k (dq_k - omega_k h), bounded by
h / 2 max|domega/dt| integral of |tau| dt and first order in h.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from harness import cli, registry, scenarios
from harness.drive import metrics
from harness.engines import DEFAULT_STEP, fmpy_master, result, writers
from harness.engines import libcosim as engines
from harness.engines import system as description
from harness.engines.plan import prepare
from harness.engines.result import RunResult
from harness.engines.settings import EccoSettings
from harness.fmu import osp

FRANCHETTI = scenarios.load("franchetti2021")
DEMIAN = scenarios.load("demian2022")
OSP = f"{{{writers.OSP_NS}}}"


@functools.cache
def harness_run(scenario_name: str, variant: str, step: float) -> RunResult:
    scenario = scenarios.load(scenario_name)
    return fmpy_master.run(prepare(scenario, scenario.variant(variant), step), keep_traces=True)


@pytest.mark.parametrize(("scenario", "variant", "count"), [
    (FRANCHETTI, "self_regulating", 1), (FRANCHETTI, "active_relocation", 2),
    (DEMIAN, "compensated", 2)])
def test_bonds_are_the_registered_ports_the_osp_files_declare(
        scenario: scenarios.Scenario, variant: str, count: int) -> None:
    described = description.describe(prepare(scenario, scenario.variant(variant)))
    bonds = described.bonds
    assert len(bonds) == count == len(scenario.for_variant(scenario.variant(variant)).joints)
    for bond in bonds:
        for component, effort, flow in ((bond.source, bond.source_effort, bond.source_flow),
                                        (bond.sink, bond.sink_effort, bond.sink_flow)):
            model = described.models[component]
            ports = {(p.effort, p.flow) for p in registry.registration(model).ports}
            assert (effort, flow) in ports
            # the OSP-IS file declares the same pair as one port (effort group, flow group)
            declared = {tuple(v for m in g.members for v in m.variables)
                        for g in osp.groups(model) if g.members}
            assert (effort, flow) in declared
        # effort drive -> joint, flow joint -> drive, as the system connects them
        assert (bond.source, bond.source_effort, bond.sink, bond.sink_effort) in \
            described.connections
        assert (bond.sink, bond.sink_flow, bond.source, bond.source_flow) in \
            described.connections
    joints = {(b.sink_effort, b.sink_flow) for b in bonds}
    assert joints == {(j.effort, j.speed) for j in
                      scenario.for_variant(scenario.variant(variant)).joints}


def test_harness_bond_columns_close_and_meet_their_definition() -> None:
    """demian2022 (8 s, two bonds): the CSV columns are the cumulative sums of their
    definitions, the joint side is the mechanism's own W_drive ledger term (its RK4 sub-steps
    integrate tau omega), and the error stays within its step-size bound."""
    run = harness_run("demian2022", "compensated", DEFAULT_STEP)
    h = run.step_size
    rows = result.recorded_points(run.traces[0].times, h)[:len(run.series)]
    joint_total = 0.0
    for trace in run.traces:
        s = result.suffix(DEMIAN, trace.joint)
        n = len(trace.voltage)
        out = trace.effort * trace.speed[:n] * h         # no delay: the drive's own effort
        received = trace.effort * np.diff(trace.position)
        for column, per_step in (("W_bond_drive", out), ("W_bond_joint", received),
                                 ("W_bond_error", received - out)):
            cumulative = np.concatenate([[0.0], np.cumsum(per_step)])[rows]
            np.testing.assert_allclose(run.series[f"{column}{s}"], cumulative,
                                       rtol=1e-12, atol=1e-15)
            assert run.metrics[f"{column}{s}"] == pytest.approx(per_step.sum(), rel=1e-12)
        error = run.metrics[f"W_bond_error{s}"]
        acceleration = np.max(np.abs(np.diff(trace.speed))) / h
        bound = h / 2 * acceleration * np.sum(np.abs(trace.effort)) * h
        assert 0 < abs(error) <= bound
        joint_total += run.metrics[f"W_bond_joint{s}"]
    # the mechanism's ledger: W_drive is the work of tau1 and f2 together
    assert joint_total == pytest.approx(run.series.W_drive.iloc[-1], rel=1e-9)


@pytest.mark.slow   # two 35 s harness runs, about 5 s
def test_harness_bond_error_is_first_order_in_the_step() -> None:
    errors = [harness_run("franchetti2021", "self_regulating", h).metrics["W_bond_error"]
              for h in (2e-3, 1e-3)]
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.2)
    run = harness_run("franchetti2021", "self_regulating", 1e-3)
    assert run.metrics["W_bond_joint"] == pytest.approx(run.series.W_drive.iloc[-1],
                                                        rel=1e-9)


def test_ecco_osp_file_loads_in_libcosim(tmp_path: Path) -> None:
    """One bond: libcosim reads the ECCO OSP file and steps it at the step ECCO sets. Two
    bonds: libcosim 0.0.6's parser refuses the file (why the engine uses the API)."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    settings = EccoSettings(abs_tolerance=1e-6)
    described = description.describe(prepare(FRANCHETTI, FRANCHETTI.variant("self_regulating")),
                                     ecco=settings)
    path = writers.write_osp(described, tmp_path / "one")
    root = ET.parse(path).getroot()
    assert root.find(f"{OSP}Algorithm").text == "ecco"
    configuration = root.find(f"{OSP}EccoConfiguration")
    assert float(configuration.find(f"{OSP}AbsoluteTolerance").text) == 1e-6
    assert float(configuration.find(f"{OSP}MaximumStepSize").text) == settings.max_step
    bonded = [c for c in root.iter(f"{OSP}VariableConnection") if c.get("powerBond")]
    assert len(bonded) == 2 and {c.get("powerBond") for c in bonded} == {
        described.bonds[0].name}
    execution = CosimExecution.from_osp_config_file(str(path))
    execution.add_observer(CosimObserver.create_last_value())  # exposes the bonds' inputs
    assert execution.step(5)
    assert execution.status().current_time > 0
    two = description.describe(prepare(DEMIAN, DEMIAN.variant("compensated")), ecco=settings)
    with pytest.raises(AssertionError, match="number of powerbonds"):
        CosimExecution.from_osp_config_file(str(writers.write_osp(two, tmp_path / "two")))


def test_fixed_algorithm_is_the_default_and_writes_no_bond(tmp_path: Path) -> None:
    described = description.describe(prepare(FRANCHETTI, FRANCHETTI.variant("self_regulating")))
    assert described.ecco is None
    text = writers.write_osp(described, tmp_path).read_text()
    assert "<Algorithm>fixedStep</Algorithm>" in text
    assert "powerBond" not in text and "EccoConfiguration" not in text
    assert cli.parser("cosim").parse_args(["cosim"]).engine == "fmpy"


@pytest.mark.parametrize(("engine", "option", "value", "field"), [
    ("libcosim-ecco", "--ecco-min-step", "0", "min_step"),
    ("libcosim-ecco", "--ecco-abs-tolerance", "nan", "abs_tolerance"),
    ("libcosim-ecco", "--ecco-max-change-rate", "0.5", "change rates"),
    ("fmpy-ssp", "--ecco-min-step", "1e-3", "--ecco-min-step applies to --engine libcosim-ecco"),
    ("libcosim-ecco", "--source", "ssp", "--source applies to --engine libcosim only")])
def test_bad_ecco_setting_is_one_line(engine: str, option: str, value: str, field: str,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["cosim", "--engine", engine, option, value]) == 2
    error = capsys.readouterr().err.strip()
    assert field in error and len(error.splitlines()) == 1


def test_ecco_runs_demian2022_with_variable_steps_and_reports_its_events() -> None:
    """ECCO's steps vary; its E_drawn agrees with the harness's; the phases' starts are not
    all hit, and the lag it reports is the first point at or after each start, at most the
    largest step; the mechanism sees the scenario's switches no earlier than scheduled."""
    settings = EccoSettings(abs_tolerance=1e-5)
    described = description.describe(prepare(DEMIAN, DEMIAN.variant("compensated")),
                                     ecco=settings)
    run = engines.run_libcosim(described)
    harness = harness_run("demian2022", "compensated", DEFAULT_STEP)
    assert run.metrics["E_drawn"] == pytest.approx(harness.metrics["E_drawn"], rel=0.01)
    steps = run.metrics["steps"]
    assert steps < 8000  # fewer than the fixed 1 ms step's
    assert run.step_size == pytest.approx(run.series.time.iloc[-1] / steps, rel=0.01)
    # the bonds close on their own definition: error = joint side - drive side
    for joint in DEMIAN.joints:
        s = result.suffix(DEMIAN, joint)
        assert run.metrics[f"W_bond_error{s}"] == pytest.approx(
            run.metrics[f"W_bond_joint{s}"] - run.metrics[f"W_bond_drive{s}"], abs=1e-15)
    lag = run.metrics["event_lag_max"]
    assert 0 < lag <= settings.max_step


@pytest.mark.slow   # about 20 s: ECCO on the 35 s task with its locks
def test_ecco_lock_switches_at_the_first_point_after_the_phase_start() -> None:
    settings = EccoSettings(abs_tolerance=1e-6)
    described = description.describe(prepare(FRANCHETTI, FRANCHETTI.variant("self_regulating")),
                                     ecco=settings)
    run = engines.run_libcosim(described)
    series = run.series
    lag = run.metrics["event_lag_max"]
    assert 0 < lag <= settings.max_step
    switches = 0
    for _, t0, _ in FRANCHETTI.phase_times()[1:]:
        before, after = (FRANCHETTI.inputs(np.array([t]), FRANCHETTI.variant("self_regulating"))
                         for t in (t0 - 1e-6, t0))
        for name in ("slider_locked", "pulley_locked"):
            if before[name][0] == after[name][0]:
                continue
            switches += 1
            # the first recorded row with the new value: not before the phase's start, and
            # no later than the lag plus one recording interval after it
            seen = series.time[series[name] == int(after[name][0])]
            first = seen[seen > t0 - 1.0].iloc[0]
            assert t0 - 1e-9 <= first <= t0 + lag + result.RECORD_INTERVAL + 1e-9, name
    assert switches >= 2
    assert run.metrics["E_drawn"] == pytest.approx(0.0699, rel=0.01)


def test_variable_step_metrics_weigh_each_step_by_its_length() -> None:
    """A trace of unequal steps: RMS over time, and the bond's drive side sums tau omega h."""
    run = harness_run("demian2022", "compensated", DEFAULT_STEP)
    trace = run.traces[0]
    steps = np.full(len(trace.voltage), trace.step_size)
    variable = dataclasses.replace(trace, step_size=steps)
    fixed_metrics, variable_metrics = (metrics.drive_metrics(t) for t in (trace, variable))
    for name, value in fixed_metrics.items():
        assert variable_metrics[name] == pytest.approx(value, rel=1e-9, abs=1e-15), name
    np.testing.assert_allclose(variable.times, trace.times, rtol=1e-12)
    assert pd.Series(result.recorded_points(variable.times, steps)).equals(
        pd.Series(result.recorded_points(trace.times, trace.step_size)))


@pytest.mark.slow   # about 5 s: demian2022 in libcosim at the fixed step and under ECCO
def test_ecco_with_its_step_frozen_reproduces_the_fixed_step(tmp_path: Path) -> None:
    """Change rates of 1 keep ECCO at its first step (to libcosim's rounding of the step to
    the time, about 1 ns a step): the same Jacobi master as the fixed step, so the variable-
    step accounting must give the fixed step's figures."""
    fixed_system = description.describe(prepare(DEMIAN, DEMIAN.variant("compensated")))
    fixed = engines.run_libcosim(fixed_system, writers.write_osp(fixed_system, tmp_path))
    frozen = engines.run_libcosim(description.describe(
        prepare(DEMIAN, DEMIAN.variant("compensated")),
        ecco=EccoSettings(min_change_rate=1.0, max_change_rate=1.0)))
    assert frozen.metrics["steps"] == pytest.approx(DEMIAN.duration / DEFAULT_STEP,
                                                    rel=1e-3)
    for name in ("E_drawn", "E_in", "E_copper", "W_link", *(
            f"{bond}_{joint.name}" for bond in metrics.BOND for joint in DEMIAN.joints)):
        # net energies (sums of both signs) to 1e-5 of the energy drawn
        assert frozen.metrics[name] == pytest.approx(
            fixed.metrics[name], rel=1e-5, abs=1e-5 * fixed.metrics["E_drawn"]), name


@pytest.mark.slow   # about 15 s: a reference, a fixed and an ECCO run of demian2022
def test_ecco_study_table() -> None:
    from harness import bench

    table = bench.ecco(cases=[("demian2022", "compensated")], step_sizes=[2e-3],
                       tolerances=[1e-6])
    assert list(table.algorithm) == ["fixed", "ecco"]
    assert table.steps.iloc[0] == 4000 and table.event_lag_max.iloc[0] == 0.0
    # each error is its definition from the row's own figures
    np.testing.assert_allclose(table.err_E_drawn,
                               abs(table.E_drawn - table.E_drawn_ref) / table.E_drawn_ref)
    np.testing.assert_allclose(table.rel_bond_error, table.bond_error / table.E_drawn_ref)
    assert (table.err_E_drawn < 0.01).all() and (table.bond_error > 0).all()
