"""A run's plan, made once for every engine: `prepare(scenario, variant, step_size, ...)`
resolves the scenario for the variant, puts a drive on each joint, checks every name against
the model, evaluates the references and inputs on the time grid and designs each joint's
drive for the mechanism's start (`harness.drive.plan`). An engine is then
`run(plan, progress) -> RunResult`: it only runs what the plan says.

The mechanism's start (each joint's inertia, friction and static output at t = 0) is read
from its physics module (`fmu_src.mechanism.Physics`), the code its FMU runs, so that the
plan needs no FMU: `tests/test_engines.py` checks that it is the FMU's to the bit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from fmu_src import integration
from harness import registry
from harness.drive.controller import ControllerDesign, PIDGains
from harness.drive.motor import LEGACY, JointDrive, MotorParameters, motors
from harness.drive.plan import DrivePlan, JointStart, design_drive, plan_drive
from harness.engines.settings import DEFAULT_STEP
from harness.errors import UserError
from harness.scenarios import Scenario, Variant

Motors = MotorParameters | Mapping[str, MotorParameters] | None
Drives = Mapping[str, JointDrive] | None


@dataclass(frozen=True, eq=False)
class RunPlan:
    """One run of a scenario variant, as every engine runs it: the scenario resolved for the
    variant (`Scenario.for_variant`), the model and its parameters, the communication points
    k step_size [s], k = 0..n_steps, the scenario's inputs there and each phase's input
    segments (`Scenario.input_segments`), and each joint's drive, in the scenario's order."""

    scenario: Scenario
    variant: Variant
    model: str
    parameters: dict[str, float | bool]
    step_size: float
    times: np.ndarray
    inputs: dict[str, np.ndarray]
    segments: list[dict[str, tuple[Any, Any, str]]]
    drives: tuple[DrivePlan, ...]

    @property
    def name(self) -> str:
        """`<scenario>.<variant>`, e.g. an FMU instance's name."""
        return f"{self.scenario.name}.{self.variant.name}"

    @property
    def n_steps(self) -> int:
        return len(self.times) - 1

    @property
    def gains(self) -> dict[str, PIDGains]:
        """Each joint's PID gains by joint name."""
        return {d.joint.name: d.gains for d in self.drives}

    @property
    def joint_drives(self) -> list[JointDrive]:
        """Each joint's drive, in the scenario's order."""
        return [d.drive for d in self.drives]


def prepare(scenario: Scenario, variant: Variant, step_size: float = DEFAULT_STEP,
            drives: Drives = None, motor: Motors = None,
            design: ControllerDesign = ControllerDesign()) -> RunPlan:
    """The plan of one run of the variant at step_size [s]. drives: each joint's drive by
    name, else the legacy drive each joint names with motor's parameters
    (`joint_drives`). UserError naming what is wrong: the step, a name the model lacks, a
    parameter outside its range."""
    if not (step_size > 0.0 and math.isfinite(step_size)):
        raise UserError(f"step size = {step_size} s is outside (0, inf)")
    resolved = scenario.for_variant(variant)
    chosen = joint_drives(resolved, motor, drives)
    model = variant.model or resolved.model
    parameters = run_parameters(resolved, variant, [d.parameters for d in chosen])
    segments = resolved.input_segments(variant)
    starts = joint_starts(resolved, variant, model, parameters, segments, step_size)
    times = np.arange(round(resolved.duration / step_size) + 1) * step_size
    plans = tuple(
        plan_drive(joint, drive, start, design, initial, resolved.reference(times, j),
                   enabled_steps(resolved, j, times), resolved.drive_enabled(j), step_size)
        for j, (joint, drive, start, initial) in enumerate(zip(
            resolved.joints, chosen, starts, resolved.initial_angle, strict=True)))
    return RunPlan(resolved, variant, model, parameters, step_size, times,
                   resolved.inputs(times, variant), segments, plans)


def check(scenario: Scenario, variant: Variant, step_size: float | None = None,
          values: bool = True) -> None:
    """The checks of `prepare` alone, before anything runs, with the legacy drives: UserError
    naming a name the model lacks or (values) a parameter outside its range or (step_size
    [s]) a step the FMU or a joint's sampled loop does not hold."""
    resolved = scenario.for_variant(variant)
    model = variant.model or resolved.model
    chosen = joint_drives(resolved)
    parameters = run_parameters(resolved, variant, [d.parameters for d in chosen])
    segments = resolved.input_segments(variant)
    if not values:
        check_names(resolved, variant, model, parameters, segments)
        return
    starts = joint_starts(resolved, variant, model, parameters, segments, step_size)
    if step_size is not None:
        for joint, drive, start in zip(resolved.joints, chosen, starts, strict=True):
            design_drive(joint, drive, start, ControllerDesign(), step_size)


def joint_drives(scenario: Scenario, motor: Motors = None, drives: Drives = None
                 ) -> list[JointDrive]:
    """The drive of each of the scenario's joints: drives by joint name, or the legacy drive
    each joint names (`harness.drive.motor.LEGACY`) with motor's parameters (as in
    `harness.drive.motor.motors`: None, one MotorParameters replacing the geared motor, or a
    mapping by name)."""
    if drives is not None:
        missing = [joint.name for joint in scenario.joints if joint.name not in drives]
        if missing:
            raise UserError(f"scenario {scenario.name}: no drive for joint(s) "
                            f"{', '.join(missing)}")
        return [drives[joint.name] for joint in scenario.joints]
    legacy = motors(motor)
    return [replace(LEGACY[joint.motor], parameters=legacy[joint.motor])
            for joint in scenario.joints]


def run_parameters(scenario: Scenario, variant: Variant,
                   drive_motors: list[MotorParameters]) -> dict[str, float | bool]:
    """The mechanism's parameters in a run of the scenario resolved for the variant: the
    scenario's, the variant's, each joint's initial position and the inertia its drive
    reflects to it."""
    parameters = {**scenario.parameters, **variant.parameters}
    for joint, initial, drive_motor in zip(scenario.joints, scenario.initial_angle,
                                           drive_motors, strict=True):
        parameters |= {joint.start_parameter: initial, joint.drive_inertia: drive_motor.J_drive}
    return parameters


def enabled_steps(scenario: Scenario, joint: int, times: np.ndarray) -> np.ndarray:
    """Whether the joint's drive is on over each step from times[k] (len(times) - 1 values):
    that of the phase holding the step's start (`Scenario.drive_enabled`)."""
    per_phase = np.array(scenario.drive_enabled(joint), dtype=bool)
    phase = np.clip(scenario.phase_indices(times[:-1]), 0, len(per_phase) - 1)
    return per_phase[phase]


def physics_module(model: str) -> Any:
    """The pure physics module of a mechanism model; UserError for a model that is none."""
    found = registry.registration(model)
    if found is None or found.physics is None:
        raise UserError(f"unknown model {model!r}; choose from "
                        f"{', '.join(registry.mechanisms())}")
    return found.physics


def physics_parameters(physics: Any, parameters: Mapping[str, float | bool]) -> Any:
    """The physics module's validated Parameters with a run's parameters over its defaults,
    each of the field's type as the FMU takes it (a Real or a Boolean); UserError naming a
    parameter outside its range."""
    values = {f.name: f.default for f in fields(physics.Parameters)}
    values |= {name: type(values[name])(value) for name, value in parameters.items()}
    p = physics.Parameters(**values)
    try:
        physics.validate(p)
    except ValueError as error:
        raise UserError(str(error)) from None
    return p


def check_names(scenario: Scenario, variant: Variant, model: str,
                parameters: Mapping[str, float | bool],
                segments: list[dict[str, tuple[Any, Any, str]]]) -> None:
    """UserError naming a model, parameter, input or joint variable the run's model does not
    have (the scenario resolved for the variant; its parameters and input segments)."""
    physics = physics_module(model)
    declared = [f.name for f in fields(physics.Parameters)]
    unknown = [n for n in parameters if n not in declared]
    if unknown:
        raise UserError(f"model {model} has no parameter {', '.join(unknown)} (set in "
                        f"scenario {scenario.name} or variant {variant.name}); its "
                        f"parameters: {', '.join(declared)}")
    unknown = [n for n in segments[0] if n not in physics.Inputs._fields]
    if unknown:
        raise UserError(f"model {model} has no input {', '.join(unknown)}: drop it in "
                        f"variant {variant.name} (drop_inputs)")
    # a joint names inputs, outputs, states or parameters (calculated ones, which the
    # Parameters derive, included)
    variables = {*physics.Inputs._fields, *physics.Outputs._fields, *physics.State._fields}
    defaults = physics.Parameters()
    for joint in scenario.joints:
        names = (joint.position, joint.speed, joint.effort, joint.start_parameter,
                 joint.inertia, joint.friction, joint.drive_inertia, joint.static_output)
        unknown = [n for n in names if n not in variables and not hasattr(defaults, n)]
        if unknown:
            raise UserError(f"model {model} has no variable {', '.join(unknown)} "
                            f"(named by joint {joint.name})")


def joint_starts(scenario: Scenario, variant: Variant, model: str,
                 parameters: Mapping[str, float | bool],
                 segments: list[dict[str, tuple[Any, Any, str]]],
                 step_size: float | None = None) -> list[JointStart]:
    """Each joint's inertia, friction and static output at t = 0, from the model's physics
    with the run's parameters and the inputs at t = 0, its names checked first
    (`check_names`); UserError naming a parameter outside its range, or (step_size [s]) a
    first step the FMU refuses by its bound on RK4 sub-steps (`fmu_src.integration`)."""
    check_names(scenario, variant, model, parameters, segments)
    physics = physics_module(model)
    try:
        p = physics_parameters(physics, parameters)
    except UserError as error:
        raise UserError(f"model {model} (scenario {scenario.name}, variant {variant.name}): "
                        f"{error}") from None
    at_start = physics.Inputs(**scenario.inputs_at(0.0, segments))
    state = physics.initial_state(p)
    if step_size is not None:
        try:
            integration.substeps(step_size, physics.characteristic_rate(p, at_start, state))
        except integration.SubstepBoundError as error:
            raise UserError(f"step = {step_size:g} s: the {model} FMU refuses it ({error})"
                            ) from None
    outputs = physics.outputs(p, at_start, state)._asdict()
    return [JointStart(*(outputs[name] if name in outputs else getattr(p, name)
                         for name in (joint.inertia, joint.friction, joint.static_output)))
            for joint in scenario.joints]
