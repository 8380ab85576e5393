"""The FMPy master: a fixed-step loop over one mechanism FMU and, per driven joint of the
scenario, a sampled DC motor and a discrete PID, all in this process.

Per communication step k (time t = k dt), with the FMU's outputs at t, for each joint j:
  1. controller: V_j = PID_j(q_ref_j(t) - q_j(t)), limited to +-V_supply;
  2. motor: V_j and the joint speed held over the step -> step-average current and effort;
then the FMU (`harness.fmu.calls.MasterCalls.step`): set every joint's effort and the scenario
inputs that change at t, doStep(t, dt), read the joints' positions and speeds. Every output of
the FMU is read at the recording rate only (100 Hz by default). Each joint's drive
(`harness.drive.trace.SampledDrive`) records what it held and carried, from which its
`DriveTrace`, metrics and CSV columns are made. The run starts in equilibrium
(`harness.engines.setup`).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable

import numpy as np

from fmu_src.units.drive.dc_motor import armature_voltage
from harness.drive.controller import ControllerDesign, discrete_pid
from harness.drive.motor import sampled_motor
from harness.drive.trace import SampledDrive
from harness.engines import DEFAULT_STEP
from harness.engines.result import RECORD_INTERVAL, RunResult, assemble
from harness.engines.setup import (
    Drives,
    Motors,
    enabled_steps,
    joint_drive,
    joint_drives,
    joint_inertia,
    run_parameters,
)
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.calls import MasterCalls
from harness.fmu.loader import CoSimFMU
from harness.fmu.models import check_names
from harness.scenarios import Scenario, Variant

DriveStep = Callable[[int, float, float], float]  # (k, position, speed) -> effort


def run(scenario: Scenario, variant: Variant, step_size: float = DEFAULT_STEP,
        progress: Callable[[int], None] | None = None, motor: Motors = None,
        design: ControllerDesign = ControllerDesign(), fmu: CoSimFMU | None = None,
        keep_traces: bool = False, drives: Drives = None, series: bool = True) -> RunResult:
    """Co-simulate one variant of a scenario at step_size [s] and return its series and
    metrics; progress(steps) after every block of steps of RECORD_INTERVAL.

    drives: each joint's drive by name, else motor's legacy drives
    (`harness.engines.setup.joint_drives`). The variant's own joints are driven too
    (`Scenario.for_variant`); a joint that rests when holding is switched off in the phases
    that hold it (`Scenario.drive_enabled`). fmu: an instance of the variant's model to reuse (it
    is reset first and left open), e.g. one per worker in a parameter sweep; by default a new
    instance is made and freed. keep_traces: return each joint's `DriveTrace` of every step
    too (`RunResult.traces`), e.g. to replay the run's efforts. series: False records the
    mechanism's outputs at t = 0 only, for a run whose metrics alone are kept (a study's:
    reading them every RECORD_INTERVAL takes about a tenth of a run, and changes nothing of
    it).
    """
    if not (step_size > 0.0 and math.isfinite(step_size)):
        raise UserError(f"step size = {step_size} s is outside (0, inf)")
    scenario = scenario.for_variant(variant)
    joints = scenario.joints
    joint_drive_set = joint_drives(scenario, motor, drives)
    drive_motors = [drive.parameters for drive in joint_drive_set]
    model = variant.model or scenario.model
    parameters = run_parameters(scenario, variant, drive_motors)
    n_steps = round(scenario.duration / step_size)
    times = np.arange(n_steps + 1) * step_size
    references = [scenario.reference(times, j) for j in range(len(joints))]
    inputs = scenario.inputs(times, variant)
    enabled = [enabled_steps(scenario, j, times) for j in range(len(joints))]

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
        calls = MasterCalls(fmu, [joint.effort for joint in joints],
                            [name for joint in joints for name in (joint.position, joint.speed)],
                            fmu.names("output") + list(inputs), inputs, first_message)
        state = calls.read_states()
        # per joint: the PID designed for its inertia and friction, and the motor starting in
        # equilibrium (holding the static effort at the initial position)
        gains, sampled = {}, []
        for j, (joint, drive_motor) in enumerate(zip(joints, drive_motors, strict=True)):
            values = fmu.get([joint.inertia, joint.friction, joint.static_output])
            gains[joint.name], hold_current = joint_drive(values, joint, drive_motor, design)
            if not enabled[j][0]:  # off from the start: nothing to hold
                hold_current = 0.0
            pid = discrete_pid(gains[joint.name], step_size, drive_motor.V_supply)
            pid.reset(references[j][0] - state[2 * j],
                      integral=armature_voltage(drive_motor, hold_current, 0.0))
            sampled.append(SampledDrive(pid, sampled_motor(drive_motor, step_size, hold_current),
                                        references[j].tolist(), enabled[j],
                                        joint_inertia(values, joint, drive_motor)))
        run_steps(calls, [drive.step for drive in sampled], times.tolist(), step_size,
                  progress, series)
        for j, drive in enumerate(sampled):  # the joints at the end of the run
            drive.end(*calls.states[2 * j:2 * j + 2])
        messages = calls.messages()

    traces = [drive.trace(joint, step_size) for drive, joint in zip(sampled, joints, strict=True)]
    result = assemble(scenario, variant, model, calls.recorded(), traces, gains, parameters,
                      messages, drives=joint_drive_set)
    if keep_traces:
        result.traces = traces
    return result


def run_steps(calls: MasterCalls, drive_steps: list[DriveStep], step_times: list[float],
              step_size: float, progress: Callable[[int], None] | None = None,
              record: bool = True) -> None:
    """The master's loop over steps k = 0 .. len(step_times) - 2 of step_size [s]: per step,
    each joint's drive step gives its effort from the joint's position and speed at t_k
    (calls.states[2 j] and [2 j + 1]), then the FMU steps from step_times[k]
    (`MasterCalls.step`). `calls.record()` at t = 0 and (unless record is False) after every
    full block of steps of RECORD_INTERVAL, each block followed by progress(steps in it).

    FMUCallError when the FMU refuses a call."""
    efforts, states, n_steps = calls.efforts, calls.states, len(step_times) - 1
    record_every = max(1, round(RECORD_INTERVAL / step_size))
    joints = list(enumerate(drive_steps))
    calls.record()
    for first in range(0, n_steps, record_every):
        last = min(first + record_every, n_steps)
        for k in range(first, last):
            for j, drive_step in joints:
                efforts[j] = drive_step(k, states[2 * j], states[2 * j + 1])
            calls.step(k, step_times[k], step_size)
        if last - first == record_every:
            if record:
                calls.record()
            if progress is not None:
                progress(record_every)
