"""The franchetti2021 task as a system of FMUs (harness.engines.system): SSP and OSP
descriptions, runs in libcosim and in FMPy's SSP runner (the engines libcosim and fmpy-ssp),
against the harness's own FMPy loop.

The system's masters step the four FMUs in parallel (Jacobi), which delays the control loop by
two communication steps more than the harness's sequential loop; at 1 ms that moves the
drive energies by about 1e-4 (relative). The acceptance bands are 1 % on every
summary metric and 0.2 deg on theta.
"""

from __future__ import annotations

import functools
import re
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pandas as pd
import pytest
from conftest import committed_drives, fair_run
from fmpy.ssp.ssd import read_ssd

from harness import cli, scenarios
from harness.engines import fmpy_master, libcosim, writers
from harness.engines import system as description
from harness.engines.plan import prepare
from harness.engines.result import RunResult
from harness.fmu import build as fmu_build
from harness.run import results

SCENARIO = scenarios.load("franchetti2021")
VARIANT = "unbalanced"   # the largest drive energies and a non-zero static load at the start
METRIC_RTOL = 0.01
THETA_TOL = np.radians(0.2)


@functools.cache
def harness_run_of(variant: str) -> RunResult:
    """The harness's own run of the variant with its committed drives, those the command
    sizes (computed once)."""
    return fair_run(SCENARIO, variant)


@pytest.fixture(scope="module")
def harness_run() -> RunResult:
    return harness_run_of(VARIANT)


@pytest.fixture(scope="module")
def described() -> description.System:
    return description.describe(prepare(SCENARIO, SCENARIO.variant(VARIANT),
                                        drives=committed_drives(SCENARIO, VARIANT)))


def run_command(engine: str, out: Path, variant: str = VARIANT) -> pd.DataFrame:
    assert cli.main(["cosim", "--engine", engine, "--scenario", SCENARIO.name, "--variants",
                     variant, "--losses", "ideal", "--out", str(out), "--workers", "1",
                     "--quiet"]) == 0
    out = out / SCENARIO.name
    # the command adds the variant's eps baseline (unbalanced) to the runs
    run_variants = {variant, SCENARIO.baselines[variant]}
    assert {p.name for p in out.iterdir()} == {*(f"{v}.csv" for v in run_variants),
                                               "summary.csv", "franchetti2021.png"}
    return pd.read_csv(out / "summary.csv").set_index("variant")


def assert_agrees(summary: pd.DataFrame, series: pd.DataFrame,
                  harness_run: RunResult) -> None:
    variant = harness_run.variant
    expected = results.summary([harness_run], SCENARIO.baselines).set_index("variant")
    # the coupling's own error is the master's: Jacobi's delay triples it (tested apart)
    numeric = [c for c in expected.columns if c not in ("model", "step_size", "eps", "eps_W")
               and not c.startswith("W_bond_error")]
    for column in numeric:
        assert summary.loc[variant, column] == pytest.approx(
            expected.loc[variant, column], rel=METRIC_RTOL), column
    assert list(series.columns) == list(harness_run.series.columns)
    assert np.max(np.abs(series.theta - harness_run.series.theta)) < THETA_TOL


# unbalanced: the largest drive energies; self_regulating: the sequencer drives the locks, the
# payload and counterweight ramps, and the slider regulates within the system
# full-length libcosim runs (about 12 s and 18 s) are left to `make test-all`; libcosim itself
# runs every FMU in `make test` (tests/test_fmu_quality.py)
@pytest.mark.slow
@pytest.mark.parametrize("variant", [VARIANT, "self_regulating"])
def test_libcosim_runs_the_osp_system_like_the_harness(
        tmp_path: Path, variant: str) -> None:
    harness_run = harness_run_of(variant)
    summary = run_command("libcosim", tmp_path, variant)
    series = pd.read_csv(tmp_path / SCENARIO.name / f"{variant}.csv")
    assert_agrees(summary, series, harness_run)
    # closer than the acceptance band: only the loop's delay differs
    assert summary.loc[variant, "E_drawn"] == pytest.approx(
        harness_run.metrics["E_drawn"], rel=1e-3)
    assert np.max(np.abs(series.b - harness_run.series.b)) < 1e-5   # slider [m]


@pytest.mark.slow   # about 15 s: the whole 35 s task from the SSP archive
def test_libcosim_runs_the_ssp_archive_as_the_osp_file(described: description.System,
                                                       tmp_path: Path) -> None:
    ssp = writers.write_ssp(described, tmp_path / f"{VARIANT}.ssp")
    osp = writers.write_osp(described, tmp_path / "osp")
    from_ssp = libcosim.run_libcosim(described, ssp)
    from_osp = libcosim.run_libcosim(described, osp)
    assert from_ssp.metrics == from_osp.metrics
    pd.testing.assert_frame_equal(from_ssp.series, from_osp.series)


def _libcosim_end_values(osp_file: Path, steps: int) -> dict[str, float]:
    """Run an OspSystemStructure.xml for some steps; the mechanism's position and speed and
    the drive's speed input and torque output at the end."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    execution = CosimExecution.from_osp_config_file(str(osp_file))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    assert execution.step(steps)
    values = {}
    for component, names in (("mechanism", ("theta", "omega")), ("drive", ("omega", "tau_drive"))):
        index = execution.slave_index_from_instance_name(component)
        references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
        for name in names:
            (values[f"{component}.{name}"],) = observer.last_real_values(
                index, [references[name]])
    return values


def test_osp_variable_group_connections_give_the_per_variable_numbers(
        described: description.System, tmp_path: Path) -> None:
    """OspSystemStructure.xml joins the drive's shaft port to the mechanism's joint port and
    the controller's command to the drive's armature voltage by variable group (libcosim reads
    the groups from the <Model>_OspModelDescription.xml beside each FMU): the same numbers as
    the three per-variable connections; without the shaft connection the link falls."""
    by_group = writers.write_osp(described, tmp_path / "group")
    by_variable = writers.write_osp(described, tmp_path / "variable", by_group=False)
    ns = {"osp": writers.OSP_NS}
    tree = ET.parse(by_group)
    groups = {tuple((v.get("simulator"), v.get("name")) for v in c)
              for c in tree.iterfind(".//osp:VariableGroupConnection", ns)}
    assert groups == {(("drive", "shaft"), ("mechanism", "joint")),
                      (("controller", "command"), ("drive", "armature_voltage"))}
    variables = {(c[0].get("name"), c[1].get("name"))
                 for c in tree.iterfind(".//osp:VariableConnection", ns)}
    assert not variables & {("tau_drive", "tau_drive"), ("omega", "omega"), ("V", "V")}
    steps = 300
    expected = _libcosim_end_values(by_variable, steps)
    assert _libcosim_end_values(by_group, steps) == expected
    connections = tree.find(".//osp:Connections", ns)
    shaft = next(c for c in connections.iterfind("osp:VariableGroupConnection", ns)
                 if c[0].get("name") == "shaft")
    connections.remove(shaft)
    tree.write(by_group)
    cut = _libcosim_end_values(by_group, steps)
    assert expected["mechanism.theta"] == pytest.approx(np.radians(60.0))   # held at the start
    # the link falls under its weight, m g c sin(theta) >= its value at 60 deg, against its
    # inertia and the drive's rotor: at least half that torque over J times t^2
    mechanism = described.parameters["mechanism"]
    inertia = 0.16 + mechanism["J_drive"]
    fall = 0.5 * 3.0 * 9.81 * 0.2 * np.sin(np.radians(60.0)) / inertia * (steps * 1e-3) ** 2
    assert cut["drive.omega"] == 0.0
    assert cut["mechanism.theta"] - np.radians(60.0) > 0.9 * fall > 0.1


@pytest.mark.slow   # about 7 s: the whole 35 s task in FMPy's SSP runner
def test_fmpy_ssp_runner_agrees_despite_its_start(
        tmp_path: Path, harness_run: RunResult) -> None:
    """simulate_ssp starts every connected input at 0: the mechanism gets no drive torque in
    the first step although the link needs its static load held. Within the band anyway."""
    summary = run_command("fmpy-ssp", tmp_path)
    series = pd.read_csv(tmp_path / SCENARIO.name / f"{VARIANT}.csv")
    assert_agrees(summary, series, harness_run)
    assert series.tau_drive.iloc[0] == 0.0 != harness_run.series.tau_drive.iloc[0]


def test_ssd_is_valid_ssp_with_the_harness_parameters(
        described: description.System, harness_run: RunResult, tmp_path: Path) -> None:
    """The archive validates against the SSP 1.0 schemas (FMPy's read_ssd) and binds the
    harness's parameters: the variant, the PID gains, the drive's hold current."""
    ssp = writers.write_ssp(described, tmp_path / "x.ssp")
    ssd = read_ssd(str(ssp), validate=True)
    components = {c.name: c for c in ssd.system.elements}
    assert set(components) == {"sequencer", "controller", "drive", "mechanism"}
    values = {c: {p.name: p.value for b in components[c].parameterBindings
                  for s in b.parameterValues for p in s.parameters} for c in components}
    assert int(values["sequencer"]["variant_number"]) == list(SCENARIO.variants).index(VARIANT) + 1
    assert float(values["mechanism"]["k"]) == 0.0
    (gains,) = harness_run.gains.values()
    for name, value in gains._asdict().items():
        assert float(values["controller"][name]) == value, name
    # the drive starts holding the link's static load: i0 K_t N = -tau_gravity(60 deg)
    motor = described.plan.drives[0].motor
    tau_gravity = 3.0 * 9.81 * 0.2 * np.sin(np.radians(60.0))   # m g c sin(theta0), k = 0
    assert float(values["drive"]["i0"]) * motor.standstill_torque_per_amp == pytest.approx(
        -tau_gravity)
    assert float(values["drive"]["N"]) == motor.N != 111.0  # the sized drive, not the legacy
    with zipfile.ZipFile(ssp) as archive:
        assert sorted(archive.namelist()) == sorted(
            ["SystemStructure.ssd", *(f"resources/{m}.fmu" for m in described.models.values())])


@pytest.mark.slow   # about 20 s: a harness run and a libcosim run of the 35 s task
def test_libcosim_runs_active_relocation_with_the_variants_own_drive(tmp_path: Path) -> None:
    """active_relocation's own joint q (the spring anchor's carriage) gets a controller and a
    trapezoidal-screw drive of its own, fed by the sequencer's q_ref."""
    described = description.describe(prepare(SCENARIO, SCENARIO.variant("active_relocation")))
    assert set(described.models) == {"sequencer", "controller_theta", "drive_theta",
                                     "controller_q", "drive_q", "mechanism"}
    assert ("sequencer", "q_ref", "controller_q", "theta_ref") in described.connections
    assert described.parameters["drive_q"]["N"] == pytest.approx(2 * np.pi / 0.002)
    harness_run = harness_run_of("active_relocation")
    summary = run_command("libcosim", tmp_path, "active_relocation")
    series = pd.read_csv(tmp_path / SCENARIO.name / "active_relocation.csv")
    # the energies of both drives; the carriage's tracking error peaks within 1.2 % (the
    # loop's two steps of delay), outside the 1 % band of the other summary metrics
    for name in ("E_drawn", "E_in", "E_copper", "E_mech", "E_drawn_theta", "E_drawn_q",
                 "F_rms_q", "W_adjust"):
        expected = (harness_run.metrics[name] if name in harness_run.metrics
                    else harness_run.series[name].iloc[-1])
        assert summary.loc["active_relocation", name] == pytest.approx(
            expected, rel=METRIC_RTOL), name
    assert list(series.columns) == list(harness_run.series.columns)
    assert np.max(np.abs(series.theta - harness_run.series.theta)) < THETA_TOL
    assert np.max(np.abs(series.Y_B - harness_run.series.Y_B)) < 1e-4     # anchor [m]


@pytest.mark.slow   # about 7 s: a harness run and a libcosim run of the 8 s task
def test_libcosim_runs_the_two_drive_demian2022_system_like_the_harness(
        tmp_path: Path) -> None:
    """demian2022 as a system of six FMUs: a sequencer built for the scenario, a controller
    and a drive per joint (the lead-screw drive on q2), the compensator. Compensated: the
    smallest drive energies, where the loop's delay weighs most."""
    demian = scenarios.load("demian2022")
    variant = demian.variant("compensated")
    described = description.describe(prepare(demian, variant))
    assert set(described.models) == {"sequencer", "controller_q1", "drive_q1",
                                     "controller_q2", "drive_q2", "mechanism"}
    assert described.parameters["drive_q2"]["N"] == pytest.approx(2 * np.pi / 0.04)  # screw
    ns = {"osp": writers.OSP_NS}
    tree = ET.parse(writers.write_osp(described, tmp_path / "osp"))
    groups = {tuple((v.get("simulator"), v.get("name")) for v in c)
              for c in tree.iterfind(".//osp:VariableGroupConnection", ns)}
    # the q1 drive meets the revolute joint port to port; the lead-screw drive's shaft is
    # declared angular, so it meets the prismatic joint variable by variable
    assert (("drive_q1", "shaft"), ("mechanism", "q1")) in groups
    assert not any("drive_q2" in (a[0], b[0]) and "shaft" in (a[1], b[1]) for a, b in groups)
    run = libcosim.run_libcosim(described, tmp_path / "osp" / "OspSystemStructure.xml")
    expected = fmpy_master.run(prepare(demian, variant))
    assert list(run.series.columns) == list(expected.series.columns)
    for name in ("E_drawn", "E_in", "E_copper", "E_mech", "tau_rms_q1", "F_rms_q2",
                 "i_rms_q1", "i_rms_q2", "V_peak_q1", "V_peak_q2", "track_err_rms_q1",
                 "track_err_rms_q2"):
        assert run.metrics[name] == pytest.approx(expected.metrics[name], rel=METRIC_RTOL), name
    assert run.metrics["E_drawn"] == pytest.approx(expected.metrics["E_drawn"], rel=3e-3)
    assert np.max(np.abs(run.series.q1 - expected.series.q1)) < 1e-4     # rad
    assert np.max(np.abs(run.series.q2 - expected.series.q2)) < 1e-4     # m


def test_ssd_carries_what_omsimulator_reads(described: description.System, tmp_path: Path) -> None:
    """OMSimulator 3.0 aborts on a system without its org.openmodelica annotation (fixed-step
    master), matches elements by their prefixed names, and reads no String binding: the SSD
    has the annotation in OMSimulator's documented form, a DefaultExperiment over the task,
    and only Real, Integer and Boolean bindings, each of its variable's type."""
    from fmpy import read_model_description

    ssp = writers.write_ssp(described, tmp_path / "x.ssp")
    with zipfile.ZipFile(ssp) as archive:
        text = archive.read("SystemStructure.ssd").decode()
    root = ET.fromstring(text)
    ns = writers.NS
    (master_element,) = root.findall(
        "ssd:System/ssd:Annotations/ssc:Annotation[@type='org.openmodelica']/oms:Annotations/"
        "oms:SimulationInformation/oms:FixedStepMaster", ns)
    assert master_element.get("description") == "oms-ma"
    assert float(master_element.get("stepSize")) == described.step_size
    for name in ("absoluteTolerance", "relativeTolerance"):
        assert 0.0 < float(master_element.get(name)) < 1.0
    for tag in ("<ssd:System ", "<ssc:Annotation ", "<oms:Annotations>",
                "<oms:SimulationInformation>", "<oms:FixedStepMaster ", "<ssv:Parameter "):
        assert tag in text, tag   # the qualified names OMSimulator looks for
    experiment = root.find("ssd:DefaultExperiment", ns)
    assert (float(experiment.get("startTime")), float(experiment.get("stopTime"))) == (
        0.0, SCENARIO.duration)
    for component in root.iterfind("ssd:System/ssd:Elements/ssd:Component", ns):
        variables = {v.name: v for v in read_model_description(
            described.fmus[described.models[component.get("name")]]).modelVariables}
        for parameter in component.iterfind(".//ssv:Parameter", ns):
            (value,) = list(parameter)
            kind = value.tag.split("}")[1]
            assert kind in ("Real", "Integer", "Boolean")
            assert kind == variables[parameter.get("name")].type, parameter.get("name")


# what OMSimulator's Model::importFromSnapshot accepts as children of the SSD's root
OMS_SSD_ROOT_CHILDREN = {"ssd:System", "ssd:Units", "ssd:Enumerations", "ssd:DefaultExperiment"}
# Flags.h's re_double, the number syntax OMSimulator's --stopTime takes
OMS_DOUBLE = r"((\+|-)?[0-9]+)(\.(([0-9]+)?))?((e|E)((\+|-)?)[0-9]+)?"


def test_ssd_carries_the_stop_time_omsimulator_reads(described: description.System,
                                                     tmp_path: Path) -> None:
    """OMSimulator (OpenModelica/OMSimulator at 2940ef11; the same lines in v3.0.0) takes an
    SSP's stop time from the SSD root's `ssd:DefaultExperiment` alone,
    src/OMSimulatorLib/Model.cpp:916-919 (Model::importFromSnapshot):

        else if (name == oms::ssp::Draft20180219::ssd::default_experiment)
        {
          startTime = it->attribute("startTime").as_double(0.0);
          stopTime = it->attribute("stopTime").as_double(1.0);

    (1 s when the attribute is missing or not a number), and refuses any other child of the
    root than ssd:System, ssd:Units and ssd:Enumerations ("wrong xml schema detected", :959).
    So the API (importFile, then instantiate, initialize, simulate) runs the whole task. The
    command line does not: src/OMSimulatorLib/OMSimulator.cpp:1214-1222 (oms_RunFile) sets
    the flag's value over the SSD's after importing, whether or not the flag was given,

        else if (type == ".ssp")
        {
          char* cref;
          oms_importFile(filename, &cref);
          ...
          oms_setStopTime(cref, oms::Flags::StopTime());

    and Flags.h:160 defaults it to "1", so `OMSimulator x.ssp` stops at 1 s whatever any SSP
    says; docs/using_the_fmus.md gives the command with `--stopTime` and the task's duration."""
    ssp = writers.write_ssp(described, tmp_path / "x.ssp")
    with zipfile.ZipFile(ssp) as archive:
        root = ET.fromstring(archive.read("SystemStructure.ssd"))
    prefixes = {f"{{{uri}}}": f"{prefix}:" for prefix, uri in writers.NS.items()}
    children = [prefixes[child.tag.split("}")[0] + "}"] + child.tag.split("}")[1]
                for child in root]
    assert set(children) <= OMS_SSD_ROOT_CHILDREN, children
    (experiment,) = root.findall("ssd:DefaultExperiment", writers.NS)
    for name, value in (("startTime", 0.0), ("stopTime", SCENARIO.duration)):
        literal = experiment.get(name)
        assert re.fullmatch(OMS_DOUBLE, literal) and float(literal) == value, (name, literal)
    page = Path(__file__).parents[1] / "docs" / "using_the_fmus.md"
    text = " ".join(page.read_text().split())
    duration = f"{SCENARIO.duration:g}"
    assert f"OMSimulator --stopTime {duration} build/system/franchetti2021/unbalanced.ssp" in (
        text)


def test_sequencer_variant_number_selects_the_variant_by_position() -> None:
    """variant_number k plays the k-th variant of the scenario file, as `variant` naming it
    does; 0 leaves the choice to `variant`; a number past the last variant fails
    initialisation with a message naming the range."""
    from harness.fmu.loader import CoSimFMU, FMICallException

    def played(parameters: dict[str, object], steps: int = 20, step: float = 1.0) -> np.ndarray:
        with CoSimFMU(fmu_build.fmu_path("ScenarioSequencer")) as fmu:
            fmu.slave.enterInitializationMode()
            for name, value in parameters.items():
                (reference,) = fmu.references([name])
                if isinstance(value, int):
                    fmu.slave.setInteger([reference], [value])
                else:
                    fmu.slave.setString([reference], [value])
            fmu.slave.exitInitializationMode()
            outputs = fmu.names("output")
            rows = []
            for k in range(steps):
                fmu.step(k * step, step)
                rows.append([float(v) for v in fmu.get(outputs).values()])
            return np.array(rows)

    names = list(SCENARIO.variants)
    by_name = {name: played({"variant": name}) for name in names}
    assert not np.array_equal(by_name["self_regulating"], by_name["unbalanced"])
    for number, name in enumerate(names, start=1):
        np.testing.assert_array_equal(played({"variant_number": number}), by_name[name])
    np.testing.assert_array_equal(played({"variant": "unbalanced", "variant_number": 0}),
                                  by_name["unbalanced"])
    with CoSimFMU(fmu_build.fmu_path("ScenarioSequencer")) as fmu:
        fmu.slave.enterInitializationMode()
        fmu.slave.setInteger(fmu.references(["variant_number"]), [len(names) + 1])
        with pytest.raises(FMICallException):
            fmu.slave.exitInitializationMode()
        assert any(f"variant_number = {len(names) + 1} is outside [0, {len(names)}]"
                   in m.message for m in fmu.messages)


@pytest.mark.parametrize("variant", list(SCENARIO.variants))
def test_every_input_is_connected(variant: str) -> None:
    """An unconnected input would take its start value in libcosim but may be wired to another
    signal by FMPy's SSP runner: the systems leave none unconnected."""
    from fmpy import read_model_description

    described = description.describe(prepare(SCENARIO, SCENARIO.variant(variant)))
    connected = {(component, name) for _, _, component, name in described.connections}
    for component, model in described.models.items():
        variables = read_model_description(fmu_build.fmu_path(model)).modelVariables
        inputs = {v.name for v in variables if v.causality == "input"}
        assert {(component, name) for name in inputs} <= connected, component
