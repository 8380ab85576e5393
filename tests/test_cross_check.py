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

from harness import cli, registry, scenarios
from harness.fmu import build as fmu_build
from harness.fmu import cross_check
from harness.fmu import docs as fmu_docs
from harness.fmu.loader import CoSimFMU

INPUT_MODELS = [m for m in fmu_build.MODELS if fmu_docs.reference_run(m).inputs is not None]
MECHANISMS = registry.mechanisms()


@pytest.fixture(scope="module")
def built() -> dict[str, tuple[int, bytes]]:
    """Every FMU of build/fmus (built if stale) before the cross-check: mtime [ns], bytes."""
    paths = {model: fmu_build.fmu_path(model) for model in fmu_build.MODELS}
    return {model: (path.stat().st_mtime_ns, path.read_bytes()) for model, path in paths.items()}


@pytest.fixture(scope="module")
def repo(tmp_path_factory: pytest.TempPathFactory, built: dict[str, tuple[int, bytes]]) -> Path:
    dest = tmp_path_factory.mktemp("xc")
    assert cli.main(["cross-check", "--out", str(dest)]) == 0
    return dest


def test_validate_vendor_repo_finds_no_problem(repo: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "fmpy.cross_check.validate_vendor_repo",
                           str(repo)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stdout  # its exit code is the number of problems
    # every FMU as Co-Simulation, and the mechanisms as Model Exchange too
    assert f"Validated {len(fmu_build.MODELS) + len(MECHANISMS)} FMUs" in done.stdout


@pytest.mark.parametrize("model", sorted(MECHANISMS))
def test_model_exchange_reference_is_the_co_simulation_one(repo: Path, model: str) -> None:
    """The Model Exchange folder holds the same FMU, and its reference (FMPy's CVode)
    agrees with the Co-Simulation reference within the cross-check's band (fmpy's
    validate_result); an importer rerunning it as Model Exchange reproduces it."""
    cs, me = (cross_check.model_dir(repo, model, kind) for kind in ("cs", "me"))
    assert (me / f"{model}.fmu").read_bytes() == (cs / f"{model}.fmu").read_bytes()
    reference = read_csv(me / f"{model}_ref.csv")
    assert validate_result(reference, read_csv(cs / f"{model}_ref.csv")) == 0
    options = read_ref_opt_file(me / f"{model}_ref.opt")
    inputs = read_csv(me / f"{model}_in.csv") if (me / f"{model}_in.csv").exists() else None
    rerun = simulate_fmu(str(me / f"{model}.fmu"), fmi_type="ModelExchange", input=inputs,
                         stop_time=options["StopTime"], relative_tolerance=options["RelTol"],
                         output_interval=options["StepSize"],
                         output=list(reference.dtype.names[1:]))
    assert validate_result(rerun, reference) == 0


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_the_cross_check_exports_the_built_fmu(repo: Path, built: dict[str, tuple[int, bytes]],
                                               model: str) -> None:
    """`make xc` reuses build/fmus: it rebuilds none of them (same mtime and bytes, so the
    same GUID) and publishes each byte for byte."""
    fmu = fmu_build.DEFAULT_DEST / f"{model}.fmu"
    assert (fmu.stat().st_mtime_ns, fmu.read_bytes()) == built[model]
    assert (cross_check.model_dir(repo, model) / f"{model}.fmu").read_bytes() == built[model][1]


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
    for name in [b for b in booleans if b.endswith("_enable")]:  # no joint of it rests
        assert set(np.unique(reference[name])) == {1.0}, name
    for name in [b for b in booleans if not b.endswith("_enable")]:
        assert set(np.unique(reference[name])) == {0.0, 1.0}, name
        expected = [float(scenario.inputs_at(float(t), segments)[name])
                    for t in reference["time"]]
        np.testing.assert_array_equal(reference[name], expected, err_msg=name)
    # slider and pulley are released at the start of phase III (14 s): recorded 1 ms before
    switch = np.flatnonzero(np.diff(reference["slider_locked"]))[0]
    assert reference["time"][switch:switch + 2] == pytest.approx([13.999, 14.0], abs=1e-9)


def fixed_step_importer(fmu: Path, table: np.ndarray, reference: np.ndarray,
                        clock_error: float) -> np.ndarray:
    """What fmuCheck and fmusim do: fixed steps h (the reference's StepSize), the inputs
    interpolated linearly in the table at each communication point and held over the step,
    here read at t_k + clock_error (fmuCheck's clock accumulates t += h). The reference's
    variables at its times."""
    md = read_model_description(str(fmu))
    types = {v.name: v.type for v in md.modelVariables}
    step = fmu_docs.step_size(md)
    names = table.dtype.names[1:]

    def inputs(t: float) -> dict[str, float | bool]:
        values = {n: float(np.interp(t, table["time"], table[n])) for n in names}
        return {n: bool(round(v)) if types[n] == "Boolean" else v for n, v in values.items()}

    outputs = list(reference.dtype.names[1:])
    recorded = set(np.round(reference["time"] / step).astype(int))
    rows = []
    with CoSimFMU(fmu) as instance:
        instance.initialize(inputs(0.0), stop_time=float(reference["time"][-1]))
        rows.append([float(v) for v in instance.get(outputs).values()])
        for k in range(round(reference["time"][-1] / step)):
            instance.set(inputs(k * step + clock_error))
            instance.step(k * step, step)
            if k + 1 in recorded:
                rows.append([float(v) for v in instance.get(outputs).values()])
    return np.array(rows)


def largest_difference(a: np.ndarray, b: np.ndarray) -> float:
    """The largest difference of two results, per variable relative to its range."""
    return max(np.max(np.abs(a[:, j] - b[:, j])) / (np.ptp(b[:, j]) or 1.0)
               for j in range(b.shape[1]))


@pytest.mark.parametrize("model", INPUT_MODELS)
def test_inputs_read_alike_whatever_the_importers_clock_rounding(repo: Path,
                                                                 model: str) -> None:
    """A fixed-step importer whose clock lands just before or just after each communication
    point reproduces the reference (FMPy) from the published <Model>_in.csv: no time repeats
    in it (FMPy steps to a repeated time, fixed-step importers do not) and no step falls on a
    communication point. The same importer on the documentation's table, whose steps repeat
    a time at a communication point, applies the voltage step of DcMotorDrive one step later
    when its clock is early: what made fmuCheck differ."""
    folder = cross_check.model_dir(repo, model)
    table = read_csv(folder / f"{model}_in.csv")
    reference = read_csv(folder / f"{model}_ref.csv")
    expected = np.array([list(row)[1:] for row in reference], dtype=float)
    assert np.all(np.diff(table["time"]) > 0.0)
    step = read_ref_opt_file(folder / f"{model}_ref.opt")["StepSize"]
    clock_error = 1e-9 * step
    for error in (-clock_error, clock_error):
        result = fixed_step_importer(folder / f"{model}.fmu", table, reference, error)
        assert largest_difference(result, expected) < 1e-6, error
    if model == "DcMotorDrive":
        stepped = fmu_docs.reference_run(model).inputs
        early, late = (fixed_step_importer(folder / f"{model}.fmu", stepped, reference, error)
                       for error in (-clock_error, clock_error))
        assert largest_difference(early, late) > 1e-3   # the energies, one step of 3 V
        assert largest_difference(late, expected) < 1e-6


def test_importer_inputs_keep_the_values_at_communication_points() -> None:
    """A step of the table becomes a ramp over the step before it: the same values at every
    communication point (b from t on, as FMPy applies a repeated time), the other signals'
    ramps kept; a step closer than one communication step to the row before is refused."""
    table = fmu_docs.input_table(("u", "w"), [(0.0, 0.0, 0.0), (0.1, 0.0, 1.0),
                                              (0.1, 3.0, 1.0), (0.2, 3.0, 2.0)])
    out = cross_check.importer_inputs(table, 0.01)
    np.testing.assert_allclose(np.array(out.tolist()), [
        (0.0, 0.0, 0.0), (0.09, 0.0, 0.9), (0.1, 3.0, 1.0), (0.2, 3.0, 2.0)], atol=1e-15)
    times = np.arange(21) * 0.01
    expected = {"u": np.where(times < 0.1 - 1e-12, 0.0, 3.0), "w": times * 10.0}
    for name, values in expected.items():
        np.testing.assert_allclose(np.interp(times, out["time"], out[name]), values,
                                   atol=1e-12)
    with pytest.raises(ValueError, match="within one communication step"):
        cross_check.importer_inputs(table, 0.2)
