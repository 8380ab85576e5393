"""Property tests over each FMU's parameters, inputs and step sizes (hostile values: NaN,
inf, subnormals, extremes; steps from 1e-15 s to 10 s).

Properties, for every case:
- every FMI call returns within CALL_LIMIT (the case runs in a child process: a hang or a
  crash fails the case instead of the session);
- initialisation either succeeds with finite calculated parameters and outputs, or is
  refused with an Error message naming a parameter;
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

from harness import fmu_build

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
    for step in report["steps"]:
        if step["status"] == "ok":
            assert all(math.isfinite(v) for v in step["after"].values()), (case, step)
        else:
            assert step["status"] == "status 2", (case, step)
            assert same(step["after"], step["before"]), (case, step)
    refused = sum(step["status"] != "ok" for step in report["steps"])
    assert len(errors) >= refused, report


@pytest.mark.parametrize("model", MODELS)
def test_fmu_survives_hostile_parameters_inputs_and_steps(runner: FmuRunner, model: str
                                                          ) -> None:
    @given(cases(model))
    def property_holds(case: dict[str, Any]) -> None:
        check(case, runner.run(case))

    property_holds()
