"""`python -m harness cross-check` writes a folder that the FMI cross-check's own validator
accepts, and from which an importer reproduces the reference results."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.cross_check import validate_vendor_repo
from fmpy.util import read_csv, read_ref_opt_file, validate_result

from harness import cli, cross_check, fmu_build, fmu_docs, scenarios


@pytest.fixture(scope="module")
def repo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    dest = tmp_path_factory.mktemp("xc")
    assert cli.main(["cross-check", "--dest", str(dest)]) == 0
    return dest


def test_validate_vendor_repo_finds_no_problem(repo: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "fmpy.cross_check.validate_vendor_repo",
                           str(repo)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stdout  # its exit code is the number of problems
    assert f"Validated {len(fmu_build.MODELS)} FMUs" in done.stdout


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_layout_and_files_of_each_model(repo: Path, model: str) -> None:
    folder = cross_check.model_dir(repo, model)
    md = read_model_description(str(folder / f"{model}.fmu"))
    run = fmu_docs.reference_run(model)
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    names = {p.name for p in folder.iterdir()}
    assert names == {f"{model}.fmu", f"{model}_ref.csv", f"{model}_ref.opt", "ReadMe.md",
                     *([f"{model}_in.csv"] if inputs else [])}
    assert folder.parts[-6:-1] == ("2.0", "cs", "linux64", "pythonfmu", "0.7.0")
    if inputs:  # every input, time first
        assert read_csv(folder / f"{model}_in.csv").dtype.names == ("time", *inputs)
    reference = read_csv(folder / f"{model}_ref.csv")
    assert 2 <= len(reference.dtype.names) <= 11  # time and at most 10 variables (the rules)
    opts = read_ref_opt_file(folder / f"{model}_ref.opt")
    assert (opts["StartTime"], opts["StopTime"], opts["StepSize"]) == (
        0.0, reference["time"][-1], float(md.defaultExperiment.stepSize))
    if run.inputs is not None:  # the run lasts as long as its input signals
        assert reference["time"][-1] == run.inputs["time"][-1]
    for path in folder.iterdir():
        assert path.stat().st_size < (10e6 if path.suffix == ".fmu" else 1e6), path.name


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_an_importer_reproduces_the_reference(repo: Path, model: str) -> None:
    """Simulate as an importing tool would, from the published files only (FMU, input CSV,
    options), and compare with the reference in the cross-check's band check."""
    folder = cross_check.model_dir(repo, model)
    reference = read_csv(folder / f"{model}_ref.csv")
    opts = read_ref_opt_file(folder / f"{model}_ref.opt")
    in_csv = folder / f"{model}_in.csv"
    result = simulate_fmu(str(folder / f"{model}.fmu"), start_time=opts["StartTime"],
                          stop_time=opts["StopTime"], output_interval=opts["StepSize"],
                          input=read_csv(in_csv) if in_csv.exists() else None,
                          output=list(reference.dtype.names[1:]))
    assert validate_result(result, reference, stop_time=opts["StopTime"]) == 0


def test_sequencer_reference_is_small_and_keeps_its_switches(repo: Path) -> None:
    """The ScenarioSequencer's reference covers its default experiment in a few hundred rows
    (1/8 s apart, plus both sides of every switch); its Boolean outputs are 0/1 numbers that
    the cross-check's own CSV reader reads as such, and switch where the scenario does."""
    model = "ScenarioSequencer"
    folder = cross_check.model_dir(repo, model)
    md = read_model_description(str(folder / f"{model}.fmu"))
    path = folder / f"{model}_ref.csv"
    reference = validate_vendor_repo.read_csv(str(path), [v.name for v in md.modelVariables])
    assert path.stat().st_size < 20e3 and len(reference) < 400
    assert reference["time"][-1] == float(md.defaultExperiment.stopTime)
    booleans = [v.name for v in md.modelVariables
                if v.causality == "output" and v.type == "Boolean"]
    assert booleans and set(reference.dtype.names[1:]) == {
        v.name for v in md.modelVariables if v.causality == "output"}
    scenario = scenarios.load("franchetti2021")
    variant = next(v.start for v in md.modelVariables if v.name == "variant")
    segments = scenario.input_segments(scenario.variant(variant))
    for name in booleans:
        assert set(np.unique(reference[name])) == {0.0, 1.0}, name
        expected = [float(scenario.inputs_at(float(t), segments)[name])
                    for t in reference["time"]]
        np.testing.assert_array_equal(reference[name], expected, err_msg=name)
    # slider and pulley are released at the start of phase III (14 s): recorded 1 ms before
    switch = np.flatnonzero(np.diff(reference["slider_locked"]))[0]
    assert reference["time"][switch:switch + 2] == pytest.approx([13.999, 14.0], abs=1e-9)
