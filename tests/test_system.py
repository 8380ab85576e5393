"""The franchetti2021 task as a system of FMUs (harness.system): SSP and OSP descriptions,
runs in libcosim and in FMPy's SSP runner, against the harness's own FMPy loop.

The system's masters step the four FMUs in parallel (Jacobi), which delays the control loop by
two communication steps more than the harness's sequential loop; at 1 ms that moves the
drive energies by about 1e-4 (relative). The acceptance bands are 1 % on every
summary metric and 0.2 deg on theta.
"""

from __future__ import annotations

import functools
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from fmpy.ssp.ssd import read_ssd

from harness import cli, fmu_build, master, results, scenarios, system
from harness.drive import motors

SCENARIO = scenarios.load("franchetti2021")
VARIANT = "unbalanced"   # the largest drive energies and a non-zero static load at the start
METRIC_RTOL = 0.01
THETA_TOL = np.radians(0.2)


@functools.cache
def harness_run_of(variant: str) -> master.RunResult:
    """The harness's own run of the variant (computed once)."""
    return master.run(SCENARIO, SCENARIO.variant(variant))


@pytest.fixture(scope="module")
def harness_run() -> master.RunResult:
    return harness_run_of(VARIANT)


@pytest.fixture(scope="module")
def described() -> system.System:
    return system.describe(SCENARIO, SCENARIO.variant(VARIANT))


def run_command(engine: str, out: Path, variant: str = VARIANT) -> pd.DataFrame:
    assert cli.main(["system", "--engine", engine, "--variant", variant, "--out", str(out)]) == 0
    # the command adds the variant's eps baseline (unbalanced) to the runs
    run_variants = {variant, SCENARIO.baselines[variant]}
    assert {p.name for p in out.iterdir()} == {*(f"{v}.csv" for v in run_variants),
                                               "summary.csv", "franchetti2021.png"}
    return pd.read_csv(out / "summary.csv").set_index("variant")


def assert_agrees(summary: pd.DataFrame, series: pd.DataFrame,
                  harness_run: master.RunResult) -> None:
    variant = harness_run.variant
    expected = results.summary([harness_run], SCENARIO.baselines).set_index("variant")
    numeric = [c for c in expected.columns if c not in ("model", "step_size", "eps", "eps_W")]
    for column in numeric:
        assert summary.loc[variant, column] == pytest.approx(
            expected.loc[variant, column], rel=METRIC_RTOL), column
    assert list(series.columns) == list(harness_run.series.columns)
    assert np.max(np.abs(series.theta - harness_run.series.theta)) < THETA_TOL


# unbalanced: the largest drive energies; self_regulating: the sequencer drives the locks, the
# payload and counterweight ramps, and the slider regulates within the system
@pytest.mark.parametrize("variant", [VARIANT, "self_regulating"])
def test_libcosim_runs_the_osp_system_like_the_harness(
        tmp_path: Path, variant: str) -> None:
    harness_run = harness_run_of(variant)
    summary = run_command("libcosim", tmp_path, variant)
    series = pd.read_csv(tmp_path / f"{variant}.csv")
    assert_agrees(summary, series, harness_run)
    # closer than the acceptance band: only the loop's delay differs
    assert summary.loc[variant, "E_drawn"] == pytest.approx(
        harness_run.metrics["E_drawn"], rel=1e-3)
    assert np.max(np.abs(series.b - harness_run.series.b)) < 1e-5   # slider [m]


def test_libcosim_runs_the_ssp_archive_as_the_osp_file(described: system.System,
                                                       tmp_path: Path) -> None:
    ssp = system.write_ssp(described, tmp_path / f"{VARIANT}.ssp")
    osp = system.write_osp(described, tmp_path / "osp")
    from_ssp = system.run_libcosim(described, ssp)
    from_osp = system.run_libcosim(described, osp)
    assert from_ssp.metrics == from_osp.metrics
    pd.testing.assert_frame_equal(from_ssp.series, from_osp.series)


def test_fmpy_ssp_runner_agrees_despite_its_start(
        tmp_path: Path, harness_run: master.RunResult) -> None:
    """simulate_ssp starts every connected input at 0: the mechanism gets no drive torque in
    the first step although the link needs its static load held. Within the band anyway."""
    summary = run_command("fmpy-ssp", tmp_path)
    series = pd.read_csv(tmp_path / f"{VARIANT}.csv")
    assert_agrees(summary, series, harness_run)
    assert series.tau_drive.iloc[0] == 0.0 != harness_run.series.tau_drive.iloc[0]


def test_ssd_is_valid_ssp_with_the_harness_parameters(
        described: system.System, harness_run: master.RunResult, tmp_path: Path) -> None:
    """The archive validates against the SSP 1.0 schemas (FMPy's read_ssd) and binds the
    harness's parameters: the variant, the PID gains, the drive's hold current."""
    ssp = system.write_ssp(described, tmp_path / "x.ssp")
    ssd = read_ssd(str(ssp), validate=True)
    components = {c.name: c for c in ssd.system.elements}
    assert set(components) == {"sequencer", "controller", "drive", "mechanism"}
    values = {c: {p.name: p.value for b in components[c].parameterBindings
                  for s in b.parameterValues for p in s.parameters} for c in components}
    assert values["sequencer"]["variant"] == VARIANT
    assert float(values["mechanism"]["k"]) == 0.0
    (gains,) = harness_run.gains.values()
    for name, value in gains._asdict().items():
        assert float(values["controller"][name]) == value, name
    # the drive starts holding the link's static load: i0 K_t N = -tau_gravity(60 deg)
    motor = motors()["geared"]
    tau_gravity = 3.0 * 9.81 * 0.2 * np.sin(np.radians(60.0))   # m g c sin(theta0), k = 0
    assert float(values["drive"]["i0"]) * motor.torque_per_amp == pytest.approx(-tau_gravity)
    with zipfile.ZipFile(ssp) as archive:
        assert sorted(archive.namelist()) == sorted(
            ["SystemStructure.ssd", *(f"resources/{m}.fmu" for m in described.models.values())])


def test_multi_joint_scenarios_are_refused() -> None:
    demian = scenarios.load("demian2022")
    with pytest.raises(ValueError, match="one-joint"):
        system.describe(demian, demian.variant("compensated"))


def test_variants_with_joints_of_their_own_are_refused() -> None:
    with pytest.raises(ValueError, match="variant active_relocation drives joints of its own "
                       r"\(q\).*run it with cosim"):
        system.describe(SCENARIO, SCENARIO.variant("active_relocation"))


@pytest.mark.parametrize("variant", [v for v in SCENARIO.variants
                                     if not SCENARIO.variant(v).joints])
def test_every_input_is_connected(variant: str) -> None:
    """An unconnected input would take its start value in libcosim but may be wired to another
    signal by FMPy's SSP runner: the systems leave none unconnected."""
    from fmpy import read_model_description

    described = system.describe(SCENARIO, SCENARIO.variant(variant))
    connected = {(component, name) for _, _, component, name in described.connections}
    for component, model in described.models.items():
        variables = read_model_description(fmu_build.fmu_path(model)).modelVariables
        inputs = {v.name for v in variables if v.causality == "input"}
        assert {(component, name) for name in inputs} <= connected, component
