"""Property tests over each FMU's parameters, inputs and step sizes (hostile values: NaN,
inf, subnormals, extremes; steps from 1e-15 s to 10 s).

Properties, for every case:
- every FMI call returns within CALL_LIMIT (the case runs in a child process: a hang or a
  crash fails the case instead of the session);
- initialisation either succeeds with finite calculated parameters and outputs, or is
  refused with an Error message naming a parameter;
- an input set after initialisation is either taken (a finite value within the input's
  range and magnitudes, read back as set) or refused with fmi2Error and keeps its value;
- a step either succeeds with finite outputs, or is refused with Discard, an Error message
  naming the variable or cause, and the outputs unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import pytest
from fmpy import read_model_description
from fuzzing import CALL_LIMIT, FmuRunner, hostile_floats, step_sizes
from hypothesis import given
from hypothesis import strategies as st

from fmu_src.parameters import MAGNITUDE_LIMIT
from harness.fmu import build as fmu_build

# every FMU with numeric parameters (the sequencer's are its scenario and variant names)
MODELS = tuple(model for model in fmu_build.MODELS if model != fmu_build.SEQUENCER)
# causes a refusal may name instead of a variable
CAUSES = ("step size", "communication point", "sub-steps", "arithmetic", "initialisation")


def interface(model: str) -> dict[str, dict[str, str]]:
    """{causality: {name: type}} of a built model."""
    description = read_model_description(str(fmu_build.fmu_path(model)))
    out: dict[str, dict[str, str]] = {}
    for v in description.modelVariables:
        out.setdefault(v.causality, {})[v.name] = v.type
    return out


INTERFACES = {model: interface(model) for model in MODELS}


def input_ranges(model: str) -> dict[str, tuple[float, float]]:
    """(min, max) of each Real input of a built model, from its model description."""
    description = read_model_description(str(fmu_build.fmu_path(model)))
    return {v.name: (-math.inf if v.min is None else float(v.min),
                     math.inf if v.max is None else float(v.max))
            for v in description.modelVariables if v.causality == "input" and v.type == "Real"}


INPUT_RANGES = {model: input_ranges(model) for model in MODELS}


def values_for(variables: dict[str, str]) -> st.SearchStrategy[dict[str, Any]]:
    """A few of the variables set to hostile values (booleans for Boolean ones)."""
    if not variables:
        return st.just({})
    return st.dictionaries(st.sampled_from(sorted(variables)), hostile_floats, max_size=3).map(
        lambda chosen: {name: bool(value == value and value) if variables[name] == "Boolean"
                        else value for name, value in chosen.items()})


@st.composite
def cases(draw: st.DrawFn, model: str) -> dict[str, Any]:
    variables = INTERFACES[model]
    return {"model": model,
            "parameters": draw(values_for(variables.get("parameter", {}))),
            "inputs": draw(values_for(variables.get("input", {}))),
            "later_inputs": draw(values_for(variables.get("input", {}))),
            "steps": draw(st.lists(step_sizes, min_size=1, max_size=3))}


@pytest.fixture(scope="module")
def runner() -> Iterator[FmuRunner]:
    for model in MODELS:
        fmu_build.fmu_path(model)  # built here, not in the child
    fmu_runner = FmuRunner()
    yield fmu_runner
    fmu_runner.close()


def names_a_cause(message: str, model: str) -> bool:
    names = [n for variables in INTERFACES[model].values() for n in variables]
    return any(name in message for name in names) or any(c in message for c in CAUSES)


def acceptable(model: str, name: str, value: float | bool) -> bool:
    """An input value the FMU must take: a Boolean, or a finite number within the input's
    declared min/max and the magnitudes of fmu_src.parameters (0, or 1e-50 to 1e50)."""
    if isinstance(value, bool):
        return True
    low, high = INPUT_RANGES[model][name]
    return (math.isfinite(value) and low <= value <= high
            and (value == 0.0 or 1.0 / MAGNITUDE_LIMIT <= abs(value) <= MAGNITUDE_LIMIT))


def same(a: dict[str, float], b: dict[str, float]) -> bool:
    return all(x == y or (math.isnan(x) and math.isnan(y)) for x, y in
               zip(a.values(), b.values(), strict=True))


def check(case: dict[str, Any], report: dict[str, Any]) -> None:
    assert "exception" not in report, report
    assert report["slowest"] < CALL_LIMIT, (case, report["slowest"])
    errors = [text for status, text in report["messages"] if status == "Error"]
    for text in errors:
        assert "Traceback" not in text and names_a_cause(text, case["model"]), text
    if report["init"] != "ok":
        assert report["init"] == "status 3" and errors, report  # fmi2Error
        assert any(name in errors[0] for name in {**case["parameters"], **case["inputs"]}), (
            case, errors)
        return
    for set_ in report["sets"]:
        value = set_["value"]
        if set_["status"] == "ok":
            assert set_["after"] == value and acceptable(case["model"], set_["name"], value), (
                case, set_)
        else:
            assert set_["status"] == "status 3", (case, set_)  # fmi2Error
            assert same({"v": set_["after"]}, {"v": set_["before"]}), (case, set_)
            assert not acceptable(case["model"], set_["name"], value), (case, set_)
    for step in report["steps"]:
        if step["status"] == "ok":
            assert all(math.isfinite(v) for v in step["after"].values()), (case, step)
        else:
            assert step["status"] == "status 2", (case, step)
            assert same(step["after"], step["before"]), (case, step)
    refused = sum(step["status"] != "ok" for step in report["steps"])
    assert len(errors) >= refused, report
    assert set(report["restored"]) <= {"ok"}, report  # the run goes on from the state before


@pytest.mark.parametrize("model", MODELS)
def test_fmu_survives_hostile_parameters_inputs_and_steps(runner: FmuRunner, model: str
                                                          ) -> None:
    @given(cases(model))
    def property_holds(case: dict[str, Any]) -> None:
        check(case, runner.run(case))

    property_holds()
