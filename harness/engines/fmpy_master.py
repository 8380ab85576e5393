"""The FMPy master: a fixed-step loop over one mechanism FMU and, per driven joint of the
scenario, a sampled DC motor and a discrete PID, all in this process.

Per communication step k (time t = k dt), with the FMU's outputs at t, for each joint j:
  1. controller: V_j = PID_j(q_ref_j(t) - q_j(t)), limited to +-V_supply;
  2. motor: V_j and the joint speed held over the step -> step-average current and effort;
then the FMU (`harness.fmu.calls.MasterCalls.step`): set every joint's effort and the scenario
inputs that change at t, doStep(t, dt), read the joints' positions and speeds. Every output of
the FMU is read at the recording rate only (100 Hz by default). Each joint's drive
(`harness.drive.trace.SampledDrive`) records what it held and carried, from which its
`DriveTrace`, metrics and CSV columns are made. The run starts in equilibrium, as its plan
says (`harness.engines.plan`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

from harness.engines.plan import RunPlan
from harness.engines.result import RECORD_INTERVAL, RunResult, assemble
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.calls import MasterCalls
from harness.fmu.loader import CoSimFMU

DriveStep = Callable[[int, float, float], float]  # (k, position, speed) -> effort


def run(plan: RunPlan, progress: Callable[[int], None] | None = None,
        fmu: CoSimFMU | None = None, keep_traces: bool = False,
        series: bool = True) -> RunResult:
    """Co-simulate one planned run and return its series and metrics; progress(steps) after
    every block of steps of RECORD_INTERVAL.

    fmu: an instance of the plan's model to reuse (it is reset first and left open), e.g.
    one per worker in a parameter sweep; by default a new instance is made and freed.
    keep_traces: return each joint's `DriveTrace` of every step too (`RunResult.traces`),
    e.g. to replay the run's efforts. series: False records the mechanism's outputs at t = 0
    only, for a run whose metrics alone are kept (a study's: reading them every
    RECORD_INTERVAL takes about a tenth of a run, and changes nothing of it).
    """
    joints = plan.scenario.joints
    if fmu is None:
        context = CoSimFMU(fmu_build.locate(plan.model), plan.name)
    else:
        if fmu.model_description.modelName != plan.model:
            raise UserError(f"variant {plan.variant.name} needs model {plan.model}, "
                            f"not {fmu.model_description.modelName}")
        fmu.reset()
        context = contextlib.nullcontext(fmu)
    with context as fmu:
        calls = master_calls(plan, fmu)
        sampled = [drive.sampled() for drive in plan.drives]
        run_steps(calls, [drive.step for drive in sampled], plan.times.tolist(),
                  plan.step_size, progress, series)
        for j, drive in enumerate(sampled):  # the joints at the end of the run
            drive.end(*calls.states[2 * j:2 * j + 2])
        messages = calls.messages()

    traces = [drive.trace(joint, plan.step_size)
              for drive, joint in zip(sampled, joints, strict=True)]
    result = assemble(plan, calls.recorded(), traces, messages)
    if keep_traces:
        result.traces = traces
    return result


def master_calls(plan: RunPlan, fmu: CoSimFMU) -> MasterCalls:
    """The FMU initialised for the plan (its inputs at t = 0, then its parameters), and the
    master's calls on it (`MasterCalls`), the joints' states read at t = 0, where the first
    step starts from."""
    joints = plan.scenario.joints
    first_message = len(fmu.messages)
    fmu.set({name: signal[0] for name, signal in plan.inputs.items()})
    fmu.initialize(plan.parameters, stop_time=plan.scenario.duration)
    calls = MasterCalls(fmu, [joint.effort for joint in joints],
                        [name for joint in joints for name in (joint.position, joint.speed)],
                        fmu.names("output") + list(plan.inputs), plan.inputs, first_message)
    calls.read_states()
    return calls


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
