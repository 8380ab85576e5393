"""Co-simulation master: a fixed-step loop over one mechanism FMU, the sampled DC motor and
the discrete PID.

Per communication step k (time t = k dt), with the FMU's outputs at t:
  1. controller: V = PID(theta_ref(t) - theta(t)), limited to +-V_supply;
  2. motor: V and omega(t) held over the step -> step-average current and torque;
  3. FMU: set tau_drive and the scenario inputs of t, doStep(t, dt), read theta, omega.
Every output of the FMU is read at the recording rate only (100 Hz by default).

The run starts in equilibrium: the link at rest at the initial angle and the PID integrator
and motor current holding the static load the FMU reports at t = 0 (tau_gravity). That is
an initial condition, not a feedforward: during the task the drive gets only the error.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness import fmu_build, metrics
from harness.controller import ControllerDesign, PIDGains, design_pid, discrete_pid
from harness.drive import MotorParameters, sampled_motor
from harness.fmi import CoSimFMU
from harness.scenarios import Scenario, Variant

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
    gains: PIDGains
    parameters: dict[str, float]
    phase_work: dict[str, float] = field(default_factory=dict)
    messages: list[str] = field(default_factory=list)


def _parameter(fmu: CoSimFMU, parameters: dict[str, float], name: str) -> float:
    """A parameter's value in this run: the override, else the FMU's start value."""
    return parameters.get(name, float(fmu.variables[name].start))


def run(scenario: Scenario, variant: Variant, step_size: float = DEFAULT_STEP,
        motor: MotorParameters = MotorParameters(),
        design: ControllerDesign = ControllerDesign(),
        progress: Callable[[int], None] | None = None,
        fmu: CoSimFMU | None = None) -> RunResult:
    """Co-simulate one variant of a scenario and return its series and metrics.

    fmu: an instance of the variant's model to reuse (it is reset first and left open),
    e.g. one per worker in a parameter sweep; by default a new instance is made and freed.
    """
    if not (step_size > 0.0 and math.isfinite(step_size)):
        raise ValueError(f"step size = {step_size} s is outside (0, inf)")
    joint = scenario.joint
    model = variant.model or scenario.model
    parameters = {**scenario.parameters, **variant.parameters,
                  joint["initial_angle"]: scenario.initial_angle,
                  joint["drive_inertia"]: motor.J_drive}
    n_steps = round(scenario.duration / step_size)
    times = np.arange(n_steps + 1) * step_size
    reference = scenario.reference(times)
    inputs = scenario.inputs(times, variant)
    record_every = max(1, round(RECORD_INTERVAL / step_size))

    if fmu is None:
        context = CoSimFMU(fmu_build.fmu_path(model), f"{scenario.name}.{variant.name}")
    else:
        if fmu.model_description.modelName != model:
            raise ValueError(f"variant {variant.name} needs model {model}, "
                             f"not {fmu.model_description.modelName}")
        fmu.reset()
        context = contextlib.nullcontext(fmu)
    with context as fmu:
        first_message = len(fmu.messages)
        unknown = [n for n in inputs if n not in fmu.variables]
        if unknown:
            raise ValueError(f"model {model} has no input {', '.join(unknown)}: drop it in "
                             f"variant {variant.name} (drop_inputs)")
        fmu.set({name: signal[0] for name, signal in inputs.items()})
        fmu.initialize(parameters, stop_time=scenario.duration)
        friction = _parameter(fmu, parameters, joint["friction"])
        inertia = _parameter(fmu, parameters, joint["inertia"]) + motor.J_drive
        gains = design_pid(motor, inertia, friction, design)
        pid = discrete_pid(gains, step_size, motor.V_supply)

        outputs = fmu.names("output")
        record_names = outputs + list(inputs)
        state_refs = fmu.references([joint["angle"], joint["speed"]])
        torque_ref = fmu.references([joint["torque"]])
        slave = fmu.slave

        # start in equilibrium: hold the static load at the initial angle
        initial = fmu.get([joint["angle"], joint["speed"], "tau_gravity"])
        theta, omega = initial[joint["angle"]], initial[joint["speed"]]
        hold_current = -initial["tau_gravity"] / motor.torque_per_amp
        drive = sampled_motor(motor, step_size, current=hold_current)
        pid.reset(reference[0] - theta, integral=hold_current * motor.R_a)

        changes = _input_changes(fmu, inputs)
        voltage, current, torque, angle = [], [], [], [theta]
        rows = [fmu.get(record_names)]
        reference_list = reference.tolist()
        for k in range(n_steps):
            v = pid.update(reference_list[k] - theta)
            i_avg, tau = drive.step(v, omega)
            slave.setReal(torque_ref, [tau])
            for setter, refs, value in changes.get(k, ()):
                setter(refs, [value])
            slave.doStep(times[k], step_size)
            theta, omega = slave.getReal(state_refs)
            voltage.append(v)
            current.append(i_avg)
            torque.append(tau)
            angle.append(theta)
            if (k + 1) % record_every == 0:
                rows.append(fmu.get(record_names))
                if progress is not None:
                    progress(record_every)
        messages = [f"{m.status}: {m.message}" for m in fmu.messages[first_message:]]

    voltage, current, torque, angle = map(np.asarray, (voltage, current, torque, angle))
    dtheta = np.diff(angle)
    error = reference[:n_steps] - angle[:n_steps]
    result_metrics = metrics.drive_metrics(step_size, voltage, current, torque, dtheta, error,
                                           motor.R_a, motor.L_a, drive.current)
    series = _series(times[::record_every], rows, reference[::record_every],
                     voltage, current, torque, record_every, step_size)
    work = torque * dtheta
    phase_work = {name: float(np.sum(work[round(t0 / step_size):round(t1 / step_size)]))
                  for name, t0, t1 in scenario.phase_times()}
    return RunResult(scenario.name, variant.name, model, step_size, series, result_metrics,
                     gains, parameters, phase_work, messages)


def _input_changes(fmu: CoSimFMU, inputs: dict[str, np.ndarray]) -> dict[int, list]:
    """Input changes by step index: {k: [(setter, value references, value), ...]}.

    Inputs are set only at the communication points where they change (step 0's values are
    set before initialisation), which keeps the loop free of per-input work.
    """
    changes: dict[int, list] = {}
    for name, signal in inputs.items():
        boolean = signal.dtype == bool
        setter = fmu.slave.setBoolean if boolean else fmu.slave.setReal
        refs = fmu.references([name])
        for k in np.flatnonzero(signal[1:] != signal[:-1]) + 1:
            value = bool(signal[k]) if boolean else float(signal[k])
            changes.setdefault(int(k), []).append((setter, refs, value))
    return changes


def _series(times: np.ndarray, rows: list[dict], reference: np.ndarray, voltage: np.ndarray,
            current: np.ndarray, torque: np.ndarray, every: int, dt: float) -> pd.DataFrame:
    """Recorded FMU variables plus drive signals at the recording instants.

    The drive columns at time t_j hold the values of the step that starts at t_j (the last
    row holds those of the final step); cumulative energies are integrated up to t_j.
    """
    frame = pd.DataFrame(rows)
    frame.insert(0, "time", times[:len(frame)])
    power = voltage * current
    index = np.minimum(np.arange(len(frame)) * every, len(voltage) - 1)
    frame["theta_ref"] = reference[:len(frame)]
    frame["V"] = voltage[index]
    frame["i"] = current[index]
    frame["tau_drive"] = torque[index]
    frame["P_elec"] = power[index]
    cumulative = np.concatenate([[0.0], np.cumsum(power) * dt])
    drawn = np.concatenate([[0.0], np.cumsum(np.maximum(power, 0.0)) * dt])
    frame["E_in"] = cumulative[np.arange(len(frame)) * every]
    frame["E_drawn"] = drawn[np.arange(len(frame)) * every]
    for column in frame.columns:
        if frame[column].dtype == bool:
            frame[column] = frame[column].astype(int)
    return frame

