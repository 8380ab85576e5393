"""`python -m harness build-fmus --sequencer-scenario NAME_OR_FILE`: a ScenarioSequencer FMU
that plays another scenario than the default (franchetti2021), built without
touching the source tree, valid, and playing its scenario exactly as the harness evaluates
it, also in a process that already runs the default sequencer."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import play_sequencer
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from harness import cli, scenarios
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU

STEP = 1.0 / 64.0  # [s], a binary fraction: every phase boundary of demian2022 is a step time


@pytest.fixture(scope="module")
def demian(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sequencer built for demian2022 into a fresh folder, through the command line."""
    dest = tmp_path_factory.mktemp("sequencer")
    tree = sorted(fmu_build.SOURCE_DIR.rglob("*.py"))
    assert cli.main(["build-fmus", "--out", str(dest), "--sequencer-scenario",
                     "demian2022"]) == 0
    assert sorted(fmu_build.SOURCE_DIR.rglob("*.py")) == tree  # the module is the build's own
    assert sorted(p.name for p in dest.iterdir()) == [
        "ScenarioSequencer.fmu", "ScenarioSequencer_OspModelDescription.xml"]
    return dest / "ScenarioSequencer.fmu"


def test_the_built_fmu_declares_the_scenario(demian: Path) -> None:
    assert validate_fmu(str(demian)) == []
    md = read_model_description(str(demian))
    scenario = scenarios.load("demian2022")
    assert md.description.startswith("Scenario sequencer: plays scenario demian2022 ")
    variables = {v.name: v for v in md.modelVariables}
    # demian2022 drives no mechanism inputs: only the two joints' references and whether
    # their drives are on
    assert [v.name for v in md.modelVariables if v.causality == "output"] == [
        "q1_ref", "q1_enable", "q2_ref", "q2_enable"]
    assert variables["q1_enable"].type == "Boolean"
    assert [v.name for v in md.modelVariables if v.causality == "input"] == []
    assert variables["q1_ref"].declaredType.unit == "rad"
    assert variables["q2_ref"].declaredType.unit == "m"
    variant = variables["variant"]
    assert (variant.type, variant.start) == ("String", "compensated")
    assert ", ".join(scenario.variants) in variant.description
    assert float(md.defaultExperiment.stopTime) == scenario.duration == 8.0
    with zipfile.ZipFile(demian) as archive:
        embedded = archive.read("resources/fmu_src/units/sequencer/sequencer_scenario.py").decode()
        page = archive.read("documentation/index.html").decode()
        assert archive.getinfo("documentation/reference.png").file_size > 0
    assert embedded == scenarios.embedded_source("demian2022")
    assert "plays: harness/scenarios/demian2022.toml" in page


@pytest.mark.parametrize("variant", list(scenarios.load("demian2022").variants))
def test_it_plays_the_references_of_the_scenario(demian: Path, variant: str) -> None:
    """q1_ref and q2_ref over the whole task (and 1 s beyond) equal Scenario.reference to
    1e-12, while an instance of the default sequencer runs in the same process."""
    scenario = scenarios.load("demian2022")
    steps = round((scenario.duration + 1.0) / STEP)
    times = np.arange(steps + 1) * STEP
    with (CoSimFMU(fmu_build.fmu_path("ScenarioSequencer"), "default") as default,
          CoSimFMU(demian, "demian") as fmu):
        franchetti = play_sequencer(default, "self_regulating", 64, STEP)
        played = play_sequencer(fmu, variant, steps, STEP)
    assert set(franchetti) == {"theta_ref", "q_ref", "slider_locked", "pulley_locked",
                               "payload", "counterweight_added", "theta_enable", "q_enable"}
    assert all(played["q1_enable"]) and all(played["q2_enable"])  # no joint rests
    for j, joint in enumerate(scenario.joints):
        np.testing.assert_allclose(played[f"{joint.position}_ref"],
                                   scenario.reference(times, j), rtol=0.0, atol=1e-12)
    # the references move: out to (0.7 rad, 0.3 m) at 3 s, back to 0 at 7 s
    assert played["q1_ref"][round(3.0 / STEP)] == pytest.approx(0.7, abs=1e-12)
    assert played["q2_ref"][round(3.0 / STEP)] == pytest.approx(0.3, abs=1e-12)
    assert played["q1_ref"][-1] == played["q2_ref"][-1] == 0.0


def test_a_scenario_file_with_an_input_of_unknown_unit_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A Real input that no model of the scenario's variants has (so the sequencer has no
    unit for it): a clear error naming it, and no FMU."""
    text = (scenarios.SCENARIO_DIR / "franchetti2021.toml").read_text()
    path = tmp_path / "preload.toml"
    path.write_text(text.replace("payload = 0.0,", "payload = 0.0, spring_preload = 2.0,", 1))
    assert scenarios.load(path).phases[0].inputs["spring_preload"] == 2.0
    dest = tmp_path / "fmus"
    assert cli.main(["build-fmus", "--out", str(dest), "--sequencer-scenario",
                     str(path)]) == 2
    error = capsys.readouterr().err
    assert "preload.toml: scenario franchetti2021 drives the Real input(s) spring_preload" in error
    assert "do not have" in error
    assert not dest.exists() or not any(dest.iterdir())


@pytest.mark.parametrize("argument, message", [
    ("nonexistent", "no scenario 'nonexistent'"),
    ("broken.toml", "broken.toml: phase out: duration = 0.0 s is outside"),
])
def test_a_bad_scenario_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   argument: str, message: str) -> None:
    (tmp_path / "broken.toml").write_text(
        (scenarios.SCENARIO_DIR / "demian2022.toml").read_text().replace(
            "duration = 3.0", "duration = 0.0", 1))
    if argument.endswith(".toml"):
        argument = str(tmp_path / argument)
    assert cli.main(["build-fmus", "--out", str(tmp_path / "fmus"), "--sequencer-scenario",
                     argument]) == 2
    assert message in capsys.readouterr().err


def test_only_the_sequencer_takes_a_scenario(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="for the ScenarioSequencer, not DcMotorDrive"):
        fmu_build.build("DcMotorDrive", tmp_path, sequencer_scenario="demian2022")


def test_the_default_sequencer_switches_the_resting_drive_with_the_phases() -> None:
    """franchetti2021's active_relocation: the carriage q holds by itself, so its drive is
    on in phase III only (14-17 s, where q moves), from the step that starts at 14 s to the
    one that starts before 17 s; theta's drive is always on."""
    with CoSimFMU(fmu_build.fmu_path("ScenarioSequencer"), "relocation") as fmu:
        played = play_sequencer(fmu, "active_relocation", round(20.0 / STEP), STEP)
    times = np.arange(round(20.0 / STEP) + 1) * STEP
    on = np.asarray(played["q_enable"], dtype=bool)
    assert on.tolist() == ((times > 14.0 - STEP / 2) & (times < 17.0 - STEP / 2)).tolist()
    assert all(played["theta_enable"])
