"""What a built model offers a run: its variables by causality, and the check that a
scenario's variant names only variables its model has, made before anything runs."""

from __future__ import annotations

import functools
import zipfile
from collections.abc import Mapping

from fmpy import read_model_description

from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.scenarios import Scenario, Variant


@functools.cache
def model_variables(model: str) -> dict[str, str]:
    """{variable name: causality} of one of our models; UserError for an unknown model."""
    if model not in fmu_build.MODELS:
        raise UserError(f"unknown model {model!r}; choose from {', '.join(fmu_build.MODELS)}")
    path = fmu_build.locate(model)
    try:
        description = read_model_description(str(path))
    except (zipfile.BadZipFile, OSError) as error:  # e.g. a truncated build
        raise UserError(f"{path}: not a readable FMU ({error}); rebuild it "
                        "(python -m harness build-fmus)") from None
    return {v.name: v.causality for v in description.modelVariables}


def check_names(scenario: Scenario, variant: Variant,
                parameters: Mapping[str, float | bool]) -> None:
    """UserError naming a model, parameter, input or joint variable the run's model does not
    have: found before anything runs (a sweep checks its first point before the others)."""
    model = variant.model or scenario.model
    variables = model_variables(model)
    unknown = [n for n in parameters if variables.get(n) != "parameter"]
    if unknown:
        known = ", ".join(n for n, c in variables.items() if c == "parameter")
        raise UserError(f"model {model} has no parameter {', '.join(unknown)} (set in "
                        f"scenario {scenario.name} or variant {variant.name}); its "
                        f"parameters: {known}")
    inputs = scenario.input_segments(variant)[0]
    unknown = [n for n in inputs if variables.get(n) != "input"]
    if unknown:
        raise UserError(f"model {model} has no input {', '.join(unknown)}: drop it in "
                        f"variant {variant.name} (drop_inputs)")
    for joint in scenario.for_variant(variant).joints:
        names = (joint.position, joint.speed, joint.effort, joint.start_parameter,
                 joint.inertia, joint.friction, joint.drive_inertia, joint.static_output)
        unknown = [n for n in names if n not in variables]
        if unknown:
            raise UserError(f"model {model} has no variable {', '.join(unknown)} "
                            f"(named by joint {joint.name})")
