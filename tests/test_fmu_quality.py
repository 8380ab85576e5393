"""Quality checks every FMU of harness.fmu.build.MODELS must pass (a new model is covered by
adding it there): a valid and complete model description, documentation naming every
variable with its unit, exact state save/restore, reset, independent instances, and the same
results in DNV's libcosim as in FMPy.

Each model is excited the same generic way: its n-th Real input at n * 0.1 from
initialisation on (distinct values, so that a controller sees a non-zero error), stepped at
its DefaultExperiment step size (or its TEST_STEP). A different valid model is its first
non-zero Real parameter 5 % larger, or for a model without Real parameters (the
ScenarioSequencer: its one parameter is the String `variant`) its entry of PERTURBATIONS.
"""

from __future__ import annotations

import zipfile
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from conftest import open_fmu, run
from fmpy import read_model_description
from fmpy.validation import validate_fmu
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

from harness.fmu import build as fmu_build

STEPS = 200
INPUT_VALUE = 0.1
# Step sizes [s] of models whose first 50 + STEPS default steps would not exercise them. The
# ScenarioSequencer is a function of time only and holds still over the first 4 s of
# franchetti2021, so it steps at 1/8 s: 50 + STEPS steps reach 31.25 s, through phases I-V.
# A binary fraction, so every phase boundary is a step time, in FMPy's float seconds and in
# libcosim's integer nanoseconds alike.
TEST_STEP = {"ScenarioSequencer": 0.125}
# A different, valid model for the models without a Real parameter: the sequencer playing
# unregulated (slider and pulley stay locked, no counterweight added) instead of its
# default self_regulating.
PERTURBATIONS: dict[str, dict[str, float | bool | str]] = {
    "ScenarioSequencer": {"variant": "unregulated"}}
# libcosim runs 1 s, or a model's whole default experiment where 1 s shows too little
LIBCOSIM_WHOLE_RUN = ("ScenarioSequencer",)


@pytest.fixture(scope="module", params=fmu_build.MODELS)
def fmu_file(request: pytest.FixtureRequest) -> Path:
    return fmu_build.fmu_path(request.param)


def step_size(path: Path) -> float:
    """The step [s] the tests take: the model's TEST_STEP, else its default experiment's."""
    md = read_model_description(str(path))
    return TEST_STEP.get(md.modelName, float(md.defaultExperiment.stepSize))


def excitation(path: Path) -> dict[str, float]:
    """The n-th Real input (n = 1, 2, ...) at n * INPUT_VALUE."""
    inputs = [v.name for v in read_model_description(str(path)).modelVariables
              if v.causality == "input" and v.type == "Real"]
    return {name: n * INPUT_VALUE for n, name in enumerate(inputs, start=1)}


def perturbed_parameters(path: Path) -> dict[str, float | bool | str]:
    """A valid, different model: the first Real parameter with a non-zero default 5 % larger;
    for a model without one, its PERTURBATIONS (each value different from the default)."""
    md = read_model_description(str(path))
    first = next((v for v in md.modelVariables if v.causality == "parameter"
                  and v.type == "Real" and float(v.start) != 0.0), None)
    if first is not None:
        return {first.name: 1.05 * float(first.start)}
    assert md.modelName in PERTURBATIONS, f"{md.modelName} needs an entry in PERTURBATIONS"
    variables = {v.name: v for v in md.modelVariables}
    for name, value in PERTURBATIONS[md.modelName].items():
        assert variables[name].causality == "parameter", name
        assert str(value) != variables[name].start, name  # it changes something
    return PERTURBATIONS[md.modelName]


def outputs_of_run(path: Path, parameters: dict[str, float | bool | str] | None = None,
                   steps: int = STEPS) -> np.ndarray:
    """All outputs after each step of a run from initialisation."""
    with open_fmu(path, {**excitation(path), **(parameters or {})}) as fmu:
        return run(fmu, steps, step_size(path), fmu.names("output"))


def test_fmpy_validation_finds_no_problem(fmu_file: Path) -> None:
    assert validate_fmu(str(fmu_file)) == []


def test_model_description_is_complete(fmu_file: Path) -> None:
    """Descriptions everywhere; every Real has a unit through a declared type that
    UnitDefinitions defines; a DefaultExperiment."""
    md = read_model_description(str(fmu_file))
    units = {u.name for u in md.unitDefinitions}
    assert md.description and md.typeDefinitions and units
    for v in md.modelVariables:
        assert v.description, v.name
        if v.type == "Real":
            assert v.declaredType is not None and v.declaredType.unit in units, v.name
    experiment = md.defaultExperiment
    assert experiment is not None
    assert float(experiment.stopTime) > float(experiment.startTime)
    assert 0.0 < float(experiment.stepSize) <= float(experiment.stopTime)


class TableRows(HTMLParser):
    """The text of every table cell, row by row."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[str]] = []
        self.cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list) -> None:
        if tag == "tr":
            self.rows.append([])
        elif tag in ("td", "th"):
            self.cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th"):
            self.rows[-1].append("".join(self.cell))
            self.cell = None

    def handle_data(self, data: str) -> None:
        if self.cell is not None:
            self.cell.append(data)


def test_documentation_names_every_variable_with_its_unit(fmu_file: Path) -> None:
    """documentation/index.html has a variables table with one row per model variable
    (name, unit, causality) and shows the reference plot it ships."""
    with zipfile.ZipFile(fmu_file) as archive:
        page = archive.read("documentation/index.html").decode()
        assert archive.getinfo("documentation/reference.png").file_size > 0
    assert '<img src="reference.png"' in page
    parser = TableRows()
    parser.feed(page)
    header, *rows = parser.rows
    documented = {row[header.index("Name")]: row for row in rows}
    md = read_model_description(str(fmu_file))
    assert len(rows) == len(md.modelVariables)
    for v in md.modelVariables:
        row = documented[v.name]
        unit = v.declaredType.unit if v.declaredType is not None else ""
        assert row[header.index("Unit")] == unit, v.name
        assert row[header.index("Causality")] == v.causality, v.name
        assert row[header.index("Description")] == v.description, v.name


def test_state_restore_replays_exactly(fmu_file: Path) -> None:
    """getFMUstate, N steps, setFMUstate, the same N steps: identical outputs; likewise after
    fmi2SerializeFMUstate / fmi2DeSerializeFMUstate."""
    dt = step_size(fmu_file)
    with open_fmu(fmu_file, excitation(fmu_file)) as fmu:
        outputs = fmu.names("output")
        run(fmu, 50, dt, outputs)
        state = fmu.slave.getFMUstate()
        serialized = fmu.slave.serializeFMUstate(state)
        first = run(fmu, STEPS, dt, outputs, start_time=50 * dt)
        fmu.slave.setFMUstate(state)
        again = run(fmu, STEPS, dt, outputs, start_time=50 * dt)
        fmu.slave.setFMUstate(fmu.slave.deSerializeFMUstate(serialized))
        restored = run(fmu, STEPS, dt, outputs, start_time=50 * dt)
        fmu.slave.freeFMUstate(state)
    assert np.ptp(first, axis=0).max() > 0.0  # the model moves: the replay means something
    np.testing.assert_array_equal(again, first)
    np.testing.assert_array_equal(restored, first)


def test_reset_then_initialisation_reproduces_the_first_run(fmu_file: Path) -> None:
    dt, inputs = step_size(fmu_file), excitation(fmu_file)
    with open_fmu(fmu_file, inputs) as fmu:
        outputs = fmu.names("output")
        first = run(fmu, STEPS, dt, outputs)
        fmu.reset()
        fmu.initialize(inputs)
        second = run(fmu, STEPS, dt, outputs)
    np.testing.assert_array_equal(second, first)


def test_reset_restores_the_default_parameters(fmu_file: Path) -> None:
    """After a run of a different model (perturbed parameters), fmi2Reset and an
    initialisation without them give the run of the default model."""
    dt, inputs = step_size(fmu_file), excitation(fmu_file)
    default = outputs_of_run(fmu_file)
    with open_fmu(fmu_file, {**inputs, **perturbed_parameters(fmu_file)}) as fmu:
        outputs = fmu.names("output")
        changed = run(fmu, STEPS, dt, outputs)
        fmu.reset()
        fmu.initialize(inputs)
        after_reset = run(fmu, STEPS, dt, outputs)
    assert not np.array_equal(changed, default)
    np.testing.assert_array_equal(after_reset, default)


def test_two_instances_do_not_interfere(fmu_file: Path) -> None:
    """Interleaved stepping of two instances with different parameters gives the results of
    two separate runs (pythonfmu runs both slaves in one interpreter)."""
    dt = step_size(fmu_file)
    changed = perturbed_parameters(fmu_file)
    alone = [outputs_of_run(fmu_file), outputs_of_run(fmu_file, changed)]
    assert not np.array_equal(*alone)
    interleaved = [np.empty_like(reference) for reference in alone]
    with (open_fmu(fmu_file, excitation(fmu_file), "first") as first,
          open_fmu(fmu_file, {**excitation(fmu_file), **changed}, "second") as second):
        for k in range(STEPS):
            for fmu, rows in zip((first, second), interleaved):
                rows[k] = run(fmu, 1, dt, fmu.names("output"), k * dt)[0]
    for rows, reference in zip(interleaved, alone):
        np.testing.assert_array_equal(rows, reference)


def test_all_models_share_one_process() -> None:
    """One instance of every model, stepped in turn, each as if it ran alone."""
    paths = [fmu_build.fmu_path(model) for model in fmu_build.MODELS]
    alone = [outputs_of_run(path) for path in paths]
    fmus = [open_fmu(path, excitation(path), path.stem) for path in paths]
    try:
        rows = [np.empty_like(reference) for reference in alone]
        steps = [step_size(path) for path in paths]
        for k in range(STEPS):
            for fmu, dt, result in zip(fmus, steps, rows):
                result[k] = run(fmu, 1, dt, fmu.names("output"), k * dt)[0]
    finally:
        for fmu in fmus:
            fmu.close()
    for result, reference in zip(rows, alone):
        np.testing.assert_array_equal(result, reference)


def test_libcosim_gives_the_fmpy_results(fmu_file: Path) -> None:
    """DNV libcosim (libcosimpy) runs the same slave code: with the perturbed parameters set
    as initial values (Real, Boolean or String), all outputs, Real and Boolean, after every
    step of a run (1 s, or the whole default experiment for the models of
    LIBCOSIM_WHOLE_RUN) agree with FMPy's to 1e-9 (libcosim's step is an integer number of
    nanoseconds converted back to seconds, so results may differ in the last bits, nothing
    more), and FMPy's differ clearly from the default model's (so libcosim set them)."""
    md = read_model_description(str(fmu_file))
    dt = step_size(fmu_file)
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    duration = (float(md.defaultExperiment.stopTime) if md.modelName in LIBCOSIM_WHOLE_RUN
                else 1.0)
    steps = round(duration / dt)
    parameters = perturbed_parameters(fmu_file)
    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_step_size(step_size=round(dt * 1e9))
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(fmu_file),
                                                      instance_name="libcosim"))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer=observer)
    references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    setters = {"Real": execution.real_initial_value, "Boolean": execution.boolean_initial_value,
               "String": execution.string_initial_value}
    types = {v.name: v.type for v in md.modelVariables}
    for name, value in {**excitation(fmu_file), **parameters}.items():
        assert setters[types[name]](index, references[name], value), name

    reals = [v.name for v in outputs if v.type == "Real"]
    bools = [v.name for v in outputs if v.type == "Boolean"]
    libcosim = []
    for k in range(1, steps + 1):
        assert execution.simulate_until(target_time=k * round(dt * 1e9))
        values = dict(zip(reals, observer.last_real_values(index, [references[n]
                                                                   for n in reals])))
        if bools:  # libcosimpy refuses an empty list
            values.update(zip(bools, observer.last_boolean_values(
                index, [references[n] for n in bools])))
        libcosim.append(values)

    names = [v.name for v in outputs]
    fmpy = outputs_of_run(fmu_file, parameters, steps=steps)
    default = outputs_of_run(fmu_file, steps=steps)
    assert np.abs(fmpy - default).max() > 1e-6
    for values, row in zip(libcosim, fmpy, strict=True):
        expected = dict(zip(names, row))
        for name in reals:
            assert values[name] == pytest.approx(expected[name], rel=1e-9, abs=1e-9), name
        for name in bools:
            assert bool(values[name]) == bool(expected[name]), name


def test_a_failed_build_leaves_the_previous_fmu(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """The build writes a temporary file and renames it when the FMU and its documentation
    are complete: a failure on the way keeps the previous FMU and leaves nothing else."""
    model = fmu_build.MODELS[-1]
    fmu = fmu_build.build(model, tmp_path)
    before = fmu.read_bytes()

    def broken(*_args: object) -> None:
        raise RuntimeError("interrupted")

    monkeypatch.setattr(fmu_build.fmu_docs, "add_documentation", broken)
    with pytest.raises(RuntimeError, match="interrupted"):
        fmu_build.build(model, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        fmu.name, f"{model}_OspModelDescription.xml"]   # the first build's OSP-IS file
    assert fmu.read_bytes() == before
