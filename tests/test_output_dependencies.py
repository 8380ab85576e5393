"""ModelStructure that tells the truth: every output of every FMU declares the inputs it
depends on, and those are exactly the inputs that change it when set without a step; an
output that depends on an input shows its new value as soon as the input is set.

Each model is probed at states where every declared dependency acts (PROBES): stepped there
with the probe's inputs, then each input in turn is perturbed and set back, reading every
output in between without stepping.
"""

from __future__ import annotations

import math
import zipfile
from graphlib import CycleError, TopologicalSorter
from pathlib import Path

import pytest
from fmpy import read_model_description
from fmpy.model_description import ModelDescription
from test_fmu_quality import TableRows

from harness import registry, scenarios
from harness.engines import system as description
from harness.engines.plan import prepare
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU

# per model: the probe states (parameters and inputs held for a time; its registration's
# dependency_probes) and the initialisation probes' parameters
PROBES = {model: registry.registration(model).dependency_probes for model in fmu_build.MODELS}
INITIAL_PARAMETERS = {model: registry.registration(model).initial_parameters
                      for model in fmu_build.MODELS}


def perturbed(value: float | bool) -> float | bool:
    return not value if isinstance(value, bool) else value + 0.5


def declared(md: ModelDescription, unknowns: str) -> dict[str, set[str]]:
    """Output name -> names of the inputs among its declared dependencies (ModelStructure
    Outputs or InitialUnknowns)."""
    return {u.variable.name: {v.name for v in u.dependencies if v.causality == "input"}
            for u in getattr(md, unknowns) if u.variable.causality == "output"}


def input_names(md: ModelDescription) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == "input"]


def outputs_moved_by_each_input(fmu: CoSimFMU) -> dict[str, set[str]]:
    """Input name -> the outputs that change when it alone is perturbed, without a step.

    Each input is set back before the next, and every output must then be what it was."""
    outputs = fmu.names("output")
    before = fmu.get(outputs)
    moved = {}
    for name in fmu.names("input"):
        value = fmu.get([name])[name]
        fmu.set({name: perturbed(value)})
        moved[name] = {o for o, v in fmu.get(outputs).items() if v != before[o]}
        fmu.set({name: value})
        assert fmu.get(outputs) == before, name
    return moved


@pytest.fixture(scope="module", params=fmu_build.MODELS)
def model(request: pytest.FixtureRequest) -> tuple[str, Path]:
    return request.param, fmu_build.fmu_path(request.param)


def test_every_output_declares_its_dependencies(model: tuple[str, Path]) -> None:
    """Outputs: dependencies present and only inputs and (Model Exchange) continuous
    states, a state itself depending on itself alone; InitialUnknowns: present, every
    parameter (which the initial state is computed from) and otherwise only inputs."""
    md = read_model_description(str(model[1]))
    parameters = {v.name for v in md.modelVariables if v.causality == "parameter"}
    states = {d.variable.derivative.name for d in md.derivatives}
    assert md.outputs and all(u.dependencies is not None for u in md.outputs)
    assert all(v.causality == "input" or v.name in states
               for u in md.outputs for v in u.dependencies)
    assert all([v.name for v in u.dependencies] == [u.variable.name]
               for u in md.outputs if u.variable.name in states)
    for unknown in md.initialUnknowns:
        names = {v.name for v in unknown.dependencies}
        assert parameters <= names, unknown.variable.name
        assert names - parameters <= set(input_names(md)), unknown.variable.name


def test_documentation_names_the_dependencies(model: tuple[str, Path]) -> None:
    """The FMU's documentation/index.html gives each output's inputs, as declared."""
    with zipfile.ZipFile(model[1]) as archive:
        parser = TableRows()
        parser.feed(archive.read("documentation/index.html").decode())
    header, *rows = parser.rows
    documented = {row[header.index("Name")]: row[header.index("Depends on")] for row in rows}
    md = read_model_description(str(model[1]))
    for output, inputs in declared(md, "outputs").items():
        assert documented[output] == ", ".join(
            v.name for v in md.modelVariables if v.name in inputs), output


def test_declared_dependencies_are_what_changes_the_outputs(model: tuple[str, Path]) -> None:
    name, path = model
    md = read_model_description(str(path))
    step = float(md.defaultExperiment.stepSize)
    actual: dict[str, set[str]] = {v.name: set() for v in md.modelVariables
                                   if v.causality == "output"}
    for k, probe in enumerate(PROBES[name]):
        with CoSimFMU(path, f"probe{k}") as fmu:
            fmu.set(probe.inputs)
            fmu.initialize(probe.parameters)
            for i in range(round(probe.duration / step)):
                fmu.step(i * step, step)
            if name == "SelfRegulatingBalancer" and k == 1:
                assert fmu.get(["slider_at_stop"]) == {"slider_at_stop": True}
            for input_name, outputs in outputs_moved_by_each_input(fmu).items():
                for output in outputs:
                    actual[output].add(input_name)
    assert actual == declared(md, "outputs")


def test_declared_initial_dependencies_hold_at_initialisation(model: tuple[str, Path]) -> None:
    """An input set in initialisation mode changes only outputs whose InitialUnknowns list it,
    and each initial dependency beyond the Outputs' (an output of the last step that starts
    from the inputs at the start) does change it."""
    name, path = model
    md = read_model_description(str(path))
    inputs = PROBES[name][0].inputs
    parameters = {**PROBES[name][0].parameters, **INITIAL_PARAMETERS[name]}
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    initial = declared(md, "initialUnknowns")
    at_steps = declared(md, "outputs")
    with CoSimFMU(path, "initial") as fmu:
        fmu.initialize({**parameters, **inputs})
        before = fmu.get(outputs)
        for input_name in input_names(md):
            value = fmu.get([input_name])[input_name]
            fmu.reset()
            fmu.initialize({**parameters, **inputs, input_name: perturbed(value)})
            after = fmu.get(outputs)
            for output in outputs:
                if after[output] != before[output]:
                    assert input_name in initial[output], (output, input_name)
                elif input_name in initial[output]:
                    assert input_name in at_steps[output], (output, input_name)


def test_a_payload_set_without_a_step_shows_at_once(srb_fmu: Path) -> None:
    """fmu_src/mechanisms/self_regulating/README.md with L0 = 0:
    tau_gravity = [(m c + payload w) g - k a b] sin(theta), balance_error = (m c + payload w) g
    - k a b and E_p = (m c + payload w) g cos(theta), at the initial state (theta0, b0), from
    the payload just set."""
    start = {v.name: float(v.start) for v in read_model_description(str(srb_fmu)).modelVariables
             if v.causality == "parameter" and v.type == "Real"}
    m, c, w, k, a, b, g, theta = (start[n] for n in ("m", "c", "w", "k", "a", "b0", "g",
                                                       "theta0"))
    assert start["L0"] == 0.0 and start["m_slider"] == 0.0
    names = ["tau_gravity", "balance_error", "E_p", "theta"]
    with CoSimFMU(srb_fmu, "payload") as fmu:
        fmu.initialize()
        for payload in (1.0, 2.5, 0.0):
            fmu.set({"payload": payload})
            moment = (m * c + payload * w) * g
            expected = {"tau_gravity": (moment - k * a * b) * math.sin(theta),
                        "balance_error": moment - k * a * b, "E_p": moment * math.cos(theta),
                        "theta": theta}
            assert fmu.get(names) == pytest.approx(expected, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("name", ["SelfRegulatingBalancer", "CiupituBalancer",
                                  "PrismaticCompensator"])
def test_reading_between_set_and_step_changes_no_result(name: str) -> None:
    """Outputs recomputed on a read are only read: a host that reads every output after
    setting the inputs of each step (as an iterating master does) gets the same run."""
    path = fmu_build.fmu_path(name)
    parameters, inputs = PROBES[name][0].parameters, PROBES[name][0].inputs
    effort = next(iter(inputs))  # the first probe input is the drive effort
    runs = []
    for read_between in (False, True):
        with CoSimFMU(path, f"read{read_between}") as fmu:
            fmu.set(inputs)
            fmu.initialize(parameters)
            outputs, rows = fmu.names("output"), []
            for k in range(200):
                fmu.set({effort: math.sin(0.05 * k)})
                if read_between:
                    fmu.get(outputs)
                fmu.step(k * 1e-3, 1e-3)
                rows.append(fmu.get(outputs))
        runs.append(rows)
    assert runs[0] == runs[1]


def feedthrough_graph(described: description.System, unknowns: str | None
                      ) -> dict[tuple[str, str], set[tuple[str, str]]]:
    """(component, variable) -> the variables it is computed from at one instant: the
    output feeding each connected input, and the inputs of each output as declared in
    ModelStructure `unknowns` (None: every input, as a host must assume without them)."""
    graph: dict[tuple[str, str], set[tuple[str, str]]] = {}
    for start, output, end, input_name in described.connections:
        graph.setdefault((end, input_name), set()).add((start, output))
    for component, model in described.models.items():
        md = read_model_description(str(fmu_build.fmu_path(model)))
        every_input = set(input_names(md))
        dependencies = (declared(md, unknowns) if unknowns else
                        {v.name: every_input for v in md.modelVariables
                         if v.causality == "output"})
        for output, inputs in dependencies.items():
            graph.setdefault((component, output), set()).update(
                (component, name) for name in inputs)
    return graph


@pytest.mark.parametrize("variant", ["self_regulating", "ciupitu"])
def test_the_franchetti_system_has_no_algebraic_loop(variant: str) -> None:
    """Sequencer, controller, drive and mechanism connected as in the SSP/OSP system: with
    the declared dependencies no variable depends on itself at one communication point (nor
    at initialisation), where without them controller -> drive -> mechanism -> controller
    is a loop."""
    scenario = scenarios.load("franchetti2021")
    described = description.describe(prepare(scenario, scenario.variant(variant)))
    for unknowns in ("outputs", "initialUnknowns"):
        tuple(TopologicalSorter(feedthrough_graph(described, unknowns)).static_order())
    with pytest.raises(CycleError):
        tuple(TopologicalSorter(feedthrough_graph(described, None)).static_order())
