"""Parameter sweeps (harness.sweep): configuration paths, plans, equality with runs made one
by one, failed runs, and a sweep killed half way and restarted."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest

from harness import master, scenarios, sweep
from harness.scenarios import Ramp

DATA = Path(__file__).resolve().parent / "data"
SMALL = DATA / "sweep_small.toml"    # 2 payloads x k in (981, -1) x 2 variants
RESUME = DATA / "sweep_resume.toml"  # 12 regulation angles, one run per chunk
FRANCHETTI = scenarios.load("franchetti2021")


def test_configure_sets_paths_without_touching_the_scenario() -> None:
    scenario, motor, design = sweep.configure(FRANCHETTI, [
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
    assert design == sweep.ControllerDesign()
    # the loaded scenario is unchanged
    assert FRANCHETTI.duration == 35.0 and "L0" not in FRANCHETTI.parameters
    assert FRANCHETTI.phases[2].inputs["payload"] == Ramp(1.0)


def test_a_factor_scales_the_value_and_variant_paths_reach_its_joints() -> None:
    """regulation.toml's payload axis: the payload ramps (the scenario's and
    active_relocation's own quintic) and the anchor's travel, 58.3 mm per kg."""
    definition = sweep.load("regulation")
    assert len(sweep.plan(definition)) == 84
    assert definition.outputs == ("E_cw", "W_adjust", "E_e", "balance_error")
    scenario, _, _ = sweep.configure(FRANCHETTI, sweep.assignments(
        definition, {"payload": 3.0, "regulation_angle": 90.0}))
    variant = scenario.variant("active_relocation")
    assert variant.phase_inputs["III regulate"]["payload"] == Ramp(3.0, "quintic")
    assert variant.phase_targets["III regulate"]["q"] == pytest.approx(
        3.0 * 0.35 * 9.81 / (981.0 * 0.06), rel=1e-12)
    resolved = scenario.for_variant(variant)
    assert resolved.reference_at(17.0) == pytest.approx((math.pi / 2, 0.175), rel=1e-12)
    assert FRANCHETTI.variant("active_relocation").phase_targets["III regulate"]["q"] == (
        pytest.approx(0.0583333, rel=1e-6))
    with pytest.raises(sweep.PathError, match="'two' is not a number"):
        sweep.configure(FRANCHETTI, [("two * parameters.k", 1.0)])


@pytest.mark.parametrize("path", ['phases["III regulte"].target_deg', "parameters.L0.x",
                                  "motor.Nx", 'phases["I hold"].inputs[1]', "phases.target"])
def test_configure_rejects_bad_paths(path: str) -> None:
    with pytest.raises(ValueError, match="set path"):
        sweep.configure(FRANCHETTI, [(path, 1.0)])


def test_bad_values_fail_runs_but_bad_paths_stop_the_sweep(tmp_path: Path) -> None:
    path = tmp_path / "motor.toml"
    text = (SMALL.read_text().replace('"short_regulation.toml"',
                                      f"'{DATA / 'short_regulation.toml'}'")
            .replace('"parameters.k"', '"motor.N"').replace("[981.0, -1.0]", "[-1.0, 80.0]"))
    path.write_text(text)
    definition = sweep.load(path)
    row = sweep.run_one(definition, sweep.plan(definition)[0])
    assert row["status"] == "failed"
    assert row["error"].startswith("ValueError: ") and "N = -1.0" in row["error"]
    path.write_text(text.replace('"motor.N"', '"motor.n"'))
    with pytest.raises(sweep.PathError, match="MotorParameters has no 'n'"):
        sweep.load(path)


def test_latin_hypercube_plan_is_stratified_and_stable(tmp_path: Path) -> None:
    path = tmp_path / "lhs.toml"
    path.write_text(SMALL.read_text().replace('chunk_size = 3', 'sample = "lhs"\nsamples = 10')
                    .replace("values = [0.5, 1.5]", "range = { start = 0.0, stop = 10.0 }")
                    .replace('"short_regulation.toml"', f"'{DATA / 'short_regulation.toml'}'"))
    definition = sweep.load(path)
    runs = sweep.plan(definition)
    assert len(runs) == 20 and len({r.run_id for r in runs}) == 20
    payloads = sorted(r.values["payload"] for r in runs[::2])
    assert [math.floor(p) for p in payloads] == list(range(10))  # one per stratum
    assert {r.values["k"] for r in runs} <= {981.0, -1.0}
    assert [r.run_id for r in sweep.plan(sweep.load(path))] == [r.run_id for r in runs]


def by_hand(payload: float, k: float) -> scenarios.Scenario:
    """The short scenario with a payload and stiffness, built without harness.sweep."""
    base = scenarios.load(DATA / "short_regulation.toml")
    phases = tuple(replace(p, inputs={**p.inputs, "payload": Ramp(payload),
                                      "counterweight_added": Ramp(payload)})
                   if p.name == "regulate" else p for p in base.phases)
    return replace(base, parameters={**base.parameters, "k": k}, phases=phases)


def test_sweep_equals_runs_one_by_one_and_records_failures(tmp_path: Path) -> None:
    definition = sweep.load(SMALL)
    table = sweep.run_sweep(SMALL, tmp_path, workers=2, quiet=True)
    assert list(table.run_id) == [r.run_id for r in sweep.plan(definition)]
    assert (tmp_path / "small.csv").exists()
    assert pd.read_parquet(tmp_path / "small.parquet").equals(table)
    for row in table.itertuples():
        scenario = by_hand(row.payload, row.k)
        if row.k < 0.0:  # bad parameter: recorded, with the FMU's message
            assert row.status == "failed"
            assert "k = -1.0 N/m is outside [0.0, inf)" in row.error
            with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
                master.run(scenario, scenario.variant(row.variant))
            continue
        assert row.status == "ok" and row.error == ""
        expected = master.run(scenario, scenario.variant(row.variant)).metrics
        for metric in definition.metrics:
            assert getattr(row, metric) == expected[metric], (row.run_id, metric)
        assert row.payload_max == pytest.approx(8.2857, abs=1e-4)


def test_killed_sweep_resumes_without_losing_or_repeating_runs(tmp_path: Path) -> None:
    definition = sweep.load(RESUME)
    parts = sweep.parts_dir(definition, tmp_path)
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
    before = sweep.stored(definition, tmp_path)
    assert 3 <= len(before) < 12
    assert not (tmp_path / "resume.parquet").exists()

    table = sweep.run_sweep(RESUME, tmp_path, workers=2, quiet=True)
    planned = [r.run_id for r in sweep.plan(definition)]
    assert list(table.run_id) == planned and (table.status == "ok").all()
    stored_rows = pd.concat([pd.read_parquet(p) for p in parts.glob("part-*.parquet")])
    assert sorted(stored_rows.run_id) == sorted(planned)  # nothing computed twice
    kept = table.set_index("run_id").loc[before.run_id]
    assert list(kept.seconds) == list(before.seconds)  # the first session's rows, unchanged
    assert sweep.pending(definition, tmp_path) == []
