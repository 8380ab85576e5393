"""Co-simulation master: a fixed-step loop over one mechanism FMU and, per driven joint of
the scenario, a sampled DC motor and a discrete PID.

Per communication step k (time t = k dt), with the FMU's outputs at t, for each joint j:
  1. controller: V_j = PID_j(q_ref_j(t) - q_j(t)), limited to +-V_supply;
  2. motor: V_j and the joint speed held over the step -> step-average current and effort;
then the FMU: set every joint's effort and the scenario inputs of t, doStep(t, dt), read the
joints' positions and speeds. Every output of the FMU is read at the recording rate only
(100 Hz by default). The loop (`harness.run.loop.run_steps`) calls the FMU's fmi2SetReal,
fmi2DoStep and fmi2GetReal (and the recording's fmi2GetReal) on C arrays made once
(`FMICalls`); each joint's PID and motor are one fused function per step (`DriveLoop.step`)
that records what the drive held and carried in lists made once, from which its
`DriveTrace`, metrics and CSV columns are made.

The run starts in equilibrium: the mechanism at rest at the initial positions and each
joint's PID integrator and motor current holding the static effort the FMU reports for that
joint at t = 0 (the joint's `static_effort` or `static_load` output, e.g. tau_gravity). That is
an initial condition, not a feedforward: during the task each drive gets only its error.
"""

from __future__ import annotations

import contextlib
import functools
import math
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from fmpy import read_model_description

from fmu_src.units.drive.dc_motor import DriveEnergies, armature_voltage
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU
from harness.run import metrics
from harness.run.controller import ControllerDesign, PIDGains, design_pid, discrete_pid
from harness.run.drive import DriveTrace, MotorParameters, motors, sampled_motor
from harness.run.loop import DriveLoop, FMICalls, input_changes, run_steps
from harness.run.scenario_files import Joint, Scenario, Variant

DEFAULT_STEP = 1e-3       # communication step [s]
RECORD_INTERVAL = 0.01    # CSV sampling interval [s] (100 Hz)


@dataclass
class RunResult:
    """One co-simulation run: decimated series, metrics and the design used."""

    scenario: str
    variant: str
    model: str
    step_size: float
    series: pd.DataFrame
    metrics: dict[str, float]
    gains: dict[str, PIDGains]      # by joint name
    parameters: dict[str, float | bool]
    joint_phase_work: dict[str, dict[str, float]] = field(default_factory=dict)
    messages: list[str] = field(default_factory=list)
    traces: list[DriveTrace] = field(default_factory=list)  # per joint, if run kept them

    @property
    def phase_work(self) -> dict[str, float]:
        """Net work of the drives on the mechanism in each phase [J], summed over joints."""
        works = list(self.joint_phase_work.values())
        return {phase: sum(w[phase] for w in works) for phase in works[0]} if works else {}


def suffix(scenario: Scenario, joint: Joint) -> str:
    """Suffix of a joint's drive columns and metrics: none with one joint, else _<joint>."""
    return "" if len(scenario.joints) == 1 else f"_{joint.name}"


def run(scenario: Scenario, variant: Variant, step_size: float = DEFAULT_STEP,
        motor: MotorParameters | Mapping[str, MotorParameters] | None = None,
        design: ControllerDesign = ControllerDesign(),
        progress: Callable[[int], None] | None = None,
        fmu: CoSimFMU | None = None, keep_traces: bool = False) -> RunResult:
    """Co-simulate one variant of a scenario and return its series and metrics.

    motor: the drives by name (`harness.run.drive.motors`; default MOTORS, one MotorParameters
    replaces the geared motor). The variant's own joints are driven too
    (`Scenario.for_variant`). fmu: an instance of the variant's model to reuse (it is
    reset first and left open), e.g. one per worker in a parameter sweep; by default a new
    instance is made and freed. keep_traces: return each joint's `DriveTrace` of every step
    too (`RunResult.traces`), e.g. to replay the run's efforts.
    """
    if not (step_size > 0.0 and math.isfinite(step_size)):
        raise UserError(f"step size = {step_size} s is outside (0, inf)")
    scenario = scenario.for_variant(variant)
    joints = scenario.joints
    drive_motors = [motors(motor)[joint.motor] for joint in joints]
    model = variant.model or scenario.model
    parameters = run_parameters(scenario, variant, drive_motors)
    n_steps = round(scenario.duration / step_size)
    times = np.arange(n_steps + 1) * step_size
    references = [scenario.reference(times, j) for j in range(len(joints))]
    inputs = scenario.inputs(times, variant)
    record_every = max(1, round(RECORD_INTERVAL / step_size))

    check_names(scenario, variant, parameters)
    if fmu is None:
        context = CoSimFMU(fmu_build.locate(model), f"{scenario.name}.{variant.name}")
    else:
        if fmu.model_description.modelName != model:
            raise UserError(f"variant {variant.name} needs model {model}, "
                            f"not {fmu.model_description.modelName}")
        fmu.reset()
        context = contextlib.nullcontext(fmu)
    with context as fmu:
        first_message = len(fmu.messages)
        fmu.set({name: signal[0] for name, signal in inputs.items()})
        fmu.initialize(parameters, stop_time=scenario.duration)

        # per joint: the PID designed for its inertia and friction, and the motor starting in
        # equilibrium (holding the static effort at the initial position)
        state_names = [name for joint in joints for name in (joint.position, joint.speed)]
        state = fmu.slave.getReal(fmu.references(state_names))
        calls = FMICalls(fmu, [joint.effort for joint in joints], state_names,
                          fmu.names("output") + list(inputs), first_message)
        gains, loops = {}, []
        for j, (joint, drive_motor) in enumerate(zip(joints, drive_motors, strict=True)):
            gains[joint.name], hold_current = joint_drive(fmu, joint, drive_motor, design)
            pid = discrete_pid(gains[joint.name], step_size, drive_motor.V_supply)
            pid.reset(references[j][0] - state[2 * j],
                      integral=armature_voltage(drive_motor, hold_current, 0.0))
            loops.append(DriveLoop(pid, sampled_motor(drive_motor, step_size, hold_current),
                                   references[j].tolist(), calls.inputs, j))

        calls.states[:] = state
        run_steps(calls, input_changes(fmu, inputs),
                  [(loop.step, 2 * j) for j, loop in enumerate(loops)], times.tolist(),
                  step_size, record_every, progress)
        for j, loop in enumerate(loops):  # the joints at the end of the run
            loop.position[n_steps], loop.speed[n_steps] = calls.states[2 * j:2 * j + 2]
        messages = [f"{m.status}: {m.message}" for m in fmu.messages[first_message:]]

    traces = [loop.trace(joint, drive_motor, step_size, reference)
              for loop, joint, drive_motor, reference
              in zip(loops, joints, drive_motors, references, strict=True)]
    result = assemble(scenario, variant, model, calls.recorded(), traces, gains, parameters,
                      messages)
    if keep_traces:
        result.traces = traces
    return result


def assemble(scenario: Scenario, variant: Variant, model: str, recorded: pd.DataFrame,
             traces: list[DriveTrace], gains: dict[str, PIDGains],
             parameters: dict[str, float | bool], messages: list[str]) -> RunResult:
    """A RunResult from a run's records, whatever master produced them.

    recorded: the FMU variables recorded every RECORD_INTERVAL from t = 0, one row each;
    traces: each joint's drive over the run, in the scenario's joint order.
    """
    first = traces[0]
    times = first.times
    rows = recorded_points(times, first.step_size)[:len(recorded)]
    series = recorded.reset_index(drop=True)
    series.insert(0, "time", times[rows])
    per_joint, joint_phase_work = {}, {}
    for joint, trace in zip(scenario.joints, traces, strict=True):
        energies = trace.energies()
        per_joint[joint.name] = metrics.drive_metrics(trace)
        joint_phase_work[joint.name] = {
            name: float(np.sum(energies.W_link[point_at(times, first.step_size, t0):
                                               point_at(times, first.step_size, t1)]))
            for name, t0, t1 in scenario.phase_times()}
        _add_drive_columns(series, trace, energies, suffix(scenario, joint), rows)
    if len(scenario.joints) > 1:
        _add_total_columns(series, [suffix(scenario, joint) for joint in scenario.joints])
    for column in series.columns:
        if series[column].dtype == bool:
            series[column] = series[column].astype(int)
    run_metrics = metrics.run_metrics(per_joint)
    step_size = first.step_size
    if np.ndim(step_size) != 0:  # variable steps: the mean step, their number, the events
        run_metrics |= {"steps": len(step_size),
                        "event_lag_max": event_lag(times, scenario.phase_times())}
        step_size = float(times[-1] / len(step_size))
    return RunResult(scenario.name, variant.name, model, step_size, series, run_metrics,
                     gains, parameters, joint_phase_work, messages)


def recorded_points(times: np.ndarray, step_size: float | np.ndarray) -> np.ndarray:
    """The communication points a run records (indexes into times [s]): every
    RECORD_INTERVAL from t = 0; with variable steps the last point at or before each
    multiple of RECORD_INTERVAL (each point once)."""
    if np.ndim(step_size) == 0:
        return np.arange(0, len(times), max(1, round(RECORD_INTERVAL / step_size)))
    instants = np.arange(math.floor(times[-1] / RECORD_INTERVAL + 1e-9) + 1) * RECORD_INTERVAL
    return np.unique(np.searchsorted(times, instants + 1e-9, side="right") - 1)


def point_at(times: np.ndarray, step_size: float | np.ndarray, t: float) -> int:
    """The index of the first communication point at or after t [s] (to 1 ns): with a fixed
    step, the nearest multiple of it."""
    if np.ndim(step_size) == 0:
        return round(t / step_size)
    return int(np.searchsorted(times, t - 1e-9))


def event_lag(times: np.ndarray, phases: list[tuple[str, float, float]]) -> float:
    """The largest delay [s] between a phase's start (where the scenario's inputs switch:
    locks, payload) and the first communication point at or after it, where the mechanism
    first sees the switch; 0 when every phase starts on a communication point (to 1 ns)."""
    lags = [times[min(point_at(times, times, t0), len(times) - 1)] - t0
            for _, t0, _ in phases[1:]]
    return max((round(lag * 1e9) * 1e-9 for lag in lags), default=0.0)


def run_parameters(scenario: Scenario, variant: Variant,
                   drive_motors: list[MotorParameters]) -> dict[str, float | bool]:
    """The mechanism FMU's parameters in a run: the scenario's, the variant's, each joint's
    initial position and the inertia its drive reflects to it."""
    parameters = {**scenario.parameters, **variant.parameters}
    for joint, initial, drive_motor in zip(scenario.joints, scenario.initial_angle,
                                           drive_motors, strict=True):
        parameters |= {joint.start_parameter: initial, joint.drive_inertia: drive_motor.J_drive}
    return parameters


def joint_drive(fmu: CoSimFMU, joint: Joint, drive_motor: MotorParameters,
                design: ControllerDesign) -> tuple[PIDGains, float]:
    """For an initialised mechanism FMU: the joint's PID, designed for its inertia (plus the
    drive's) and friction, and the motor current [A] that holds the static effort the FMU
    reports for the joint, the run's equilibrium start."""
    values = fmu.get([joint.inertia, joint.friction, joint.static_output])
    gains = design_pid(drive_motor, values[joint.inertia] + drive_motor.J_drive,
                       values[joint.friction], design)
    return gains, joint.hold_effort(values[joint.static_output]) / drive_motor.torque_per_amp


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


def _add_drive_columns(frame: pd.DataFrame, trace: DriveTrace, energies: DriveEnergies,
                       suffix: str, rows: np.ndarray) -> None:
    """One drive's columns at the recorded communication points rows: `<position>_ref`, then
    V, i, the effort (named after the FMU input), P_elec, E_in and E_drawn, and the power
    bond's W_bond_drive, W_bond_joint, W_bond_error with the joint's suffix; energies: the
    trace's per-step energies.

    The drive columns at time t_j hold the values of the step that starts at t_j (the last
    row holds those of the final step); cumulative energies are summed up to t_j.
    """
    voltage, current = trace.voltage, trace.current
    index = np.minimum(rows, len(voltage) - 1)
    frame[f"{trace.joint.position}_ref"] = trace.reference[rows]
    frame[f"V{suffix}"] = voltage[index]
    frame[f"i{suffix}"] = current[index]
    frame[trace.joint.effort] = trace.effort[index]
    frame[f"P_elec{suffix}"] = (voltage * current)[index]
    per_step = {"E_in": energies.E_in, "E_drawn": energies.E_drawn,
                **dict(zip(metrics.BOND, metrics.bond_energies(trace, energies), strict=True))}
    for name, values in per_step.items():
        frame[f"{name}{suffix}"] = np.concatenate([[0.0], np.cumsum(values)])[rows]


def _add_total_columns(frame: pd.DataFrame, suffixes: list[str]) -> None:
    """P_elec, E_in and E_drawn summed over the drives."""
    for name in ("P_elec", "E_in", "E_drawn"):
        frame[name] = sum(frame[f"{name}{s}"] for s in suffixes)
