"""The monolithic reference engine: the co-simulated system as one ODE solved by scipy's
solve_ivp.

The same equations as the co-simulation, without FMI and without sampling: the
mechanism's `derivatives` from its physics module, each joint's motor armature equation, and
the continuous-time PID (filtered derivative) that each discrete controller approximates.
With the continuous controllers and no zero-order holds, this is the limit the
co-simulation converges to as the communication step shrinks; `harness bench` and the tests
measure that.

The drives' energies are integrated as extra states, their rates those of
`fmu_src.units.drive.dc_motor.drive_powers`, the definition the co-simulation's metrics share,
so the run's energy metrics are exact to the solver's tolerance. The solution is sampled at
the communication points k step_size, from which the series (every RECORD_INTERVAL) and the
effort, current and tracking metrics are read. The run is split at phase boundaries, where
the discrete inputs (locks) change; within a phase inputs are constant or ramps.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import fields
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from fmu_src.units.drive.dc_motor import (
    DriveEnergies,
    MotorParameters,
    armature_rate,
    armature_voltage,
    drive_powers,
    transmitted_effort,
)
from harness import registry
from harness.drive.controller import ControllerDesign, PIDGains, design_pid
from harness.drive.metrics import ENERGIES
from harness.drive.trace import DriveTrace
from harness.engines import DEFAULT_STEP
from harness.engines.result import RECORD_INTERVAL, RunResult, assemble
from harness.engines.setup import Drives, Motors, hold_current, joint_drives, run_parameters
from harness.errors import UserError
from harness.scenarios import Scenario, Variant, ramp

DRIVE_STATES = 3  # per joint: armature current, PID integral, filtered error
RTOL = 1e-9       # the solver's relative tolerance (its absolute one: ATOL)
ATOL = 1e-10


def supports(model: str) -> bool:
    """Whether the monolithic reference can solve the model (a mechanism whose registration
    allows it)."""
    found = registry.registration(model)
    return found is not None and found.physics is not None and found.monolithic_reference


def physics_module(model: str) -> ModuleType:
    """The pure physics module of a mechanism the monolithic reference can solve."""
    if not supports(model):
        known = [m for m, r in registry.mechanisms().items() if r.monolithic_reference]
        raise UserError(f"no monolithic reference for model {model}; known: {', '.join(known)}")
    return registry.registration(model).physics


def parameters(physics: ModuleType, scenario: Scenario, variant: Variant,
               motor: Motors = None, drives: Drives = None) -> Any:
    """The physics module's validated Parameters of a run: defaults, then the run's
    parameters (`harness.engines.setup.run_parameters`) with its drives."""
    scenario = scenario.for_variant(variant)
    values = {f.name: f.default for f in fields(physics.Parameters)}
    values.update(run_parameters(scenario, variant, [
        drive.parameters for drive in joint_drives(scenario, motor, drives)]))
    p = physics.Parameters(**values)
    physics.validate(p)
    return p


def run(scenario: Scenario, variant: Variant, step_size: float = DEFAULT_STEP,
        progress: Callable[[int], None] | None = None, motor: Motors = None,
        design: ControllerDesign = ControllerDesign(), rtol: float = RTOL,
        drives: Drives = None) -> RunResult:
    """Solve the whole task as one ODE; its series and metrics sampled at step_size [s].
    drives: each joint's drive by name, else motor's legacy drives
    (`harness.engines.setup.joint_drives`). A drive switched off for a phase
    (`Scenario.drive_enabled`) carries no current and its controller holds; switched on, its
    controller starts with the integral reset and no derivative kick."""
    model = variant.model or scenario.model
    physics = physics_module(model)
    scenario = scenario.for_variant(variant)
    joints = scenario.joints
    p = parameters(physics, scenario, variant, motor, drives)
    joint_drive_set = joint_drives(scenario, motor, drives)
    models = [drive.parameters for drive in joint_drive_set]
    enabled = [scenario.drive_enabled(j) for j in range(len(joints))]
    gains = [design_pid(m, getattr(p, joint.inertia) + m.J_drive, getattr(p, joint.friction),
                        design) for joint, m in zip(joints, models, strict=True)]
    state_names = physics.State._fields
    position_index = [state_names.index(joint.position) for joint in joints]
    speed_index = [state_names.index(joint.speed) for joint in joints]
    n_mech, n_joints = len(state_names), len(joints)
    energy_start = n_mech + DRIVE_STATES * n_joints

    def drive_states(y: np.ndarray, j: int) -> np.ndarray:
        return y[n_mech + DRIVE_STATES * j:n_mech + DRIVE_STATES * (j + 1)]

    # start in equilibrium, as the co-simulation does
    mech0 = physics.initial_state(p)
    segments = scenario.input_segments(variant)
    out0 = physics.outputs(p, _inputs(physics, joints, segments[0], 0.0, [0.0] * n_joints),
                           mech0)
    x = [*mech0]
    for j, (joint, m, i, initial) in enumerate(zip(joints, models, position_index,
                                                   scenario.initial_angle, strict=True)):
        current = (hold_current(m, joint, getattr(out0, joint.static_output))
                   if enabled[j][0] else 0.0)
        x += [current, armature_voltage(m, current, 0.0), initial - mech0[i]]
    x = np.array(x + [0.0] * (len(ENERGIES) * n_joints))

    n_steps = round(scenario.duration / step_size)
    grid = np.arange(n_steps + 1) * step_size
    every = max(1, round(RECORD_INTERVAL / step_size))  # the points between recorded rows
    # the phase of each point: that starting at or before it (to a nanosecond), the last
    # phase holding the task's end
    starts = [t0 for _, t0, _ in scenario.phase_times()]
    phase_of = np.searchsorted(starts, grid + 1e-9, side="right") - 1
    samples, outputs, signals = [], [], []
    for k, ((phase, t0, t1), segment) in enumerate(zip(scenario.phase_times(), segments,
                                                       strict=True)):
        targets = [scenario.reference_segments(j)[k][2:] for j in range(n_joints)]

        def references_at(s: float, targets=targets) -> list[float]:
            return [ramp(*target, "quintic", s) for target in targets]

        x = switch_drives(x, k, enabled, models, references_at(0.0), position_index, n_mech,
                           energy_start)

        def rhs(t: float, y: np.ndarray, t0=t0, t1=t1, segment=segment,
                references_at=references_at, k=k) -> np.ndarray:
            s = (t - t0) / (t1 - t0)
            mech = y[:n_mech]
            efforts, d_drive, d_energy = [], [], []
            for j, reference in enumerate(references_at(s)):
                effort, rates, powers = drive_rates(
                    models[j], gains[j], drive_states(y, j), reference - mech[position_index[j]],
                    mech[speed_index[j]], enabled[j][k])
                efforts.append(effort)
                d_drive += rates
                d_energy += powers
            u = _inputs(physics, joints, segment, s, efforts)
            rates = _input_rates(physics, segment, s, t1 - t0)
            return np.array([*physics.derivatives(p, u, physics.State(*mech), rates),
                             *d_drive, *d_energy])

        # the communication points of the phase (the last phase's end too), then its end
        points = np.clip(grid[phase_of == k], t0, t1)
        solution = solve_ivp(rhs, (t0, t1), x, method="Radau", rtol=rtol, atol=ATOL,
                             t_eval=np.append(points[points < t1], t1))
        if not solution.success:
            raise RuntimeError(f"reference solve failed in phase {phase}: {solution.message}")
        x = solution.y[:, -1]
        for t, y in zip(points, solution.y.T, strict=False):  # and the end if it is a point
            s = (t - t0) / (t1 - t0)
            drive = [(*drive_signals(models[j], gains[j], drive_states(y, j),
                                     reference - y[position_index[j]], y[speed_index[j]],
                                     enabled[j][k]), reference - y[position_index[j]])
                     for j, reference in enumerate(references_at(s))]
            if len(samples) % every == 0:  # a recorded row: the mechanism's outputs
                outputs.append(physics.outputs(
                    p, _inputs(physics, joints, segment, s, [d[2] for d in drive]),
                    physics.State(*y[:n_mech])))
            samples.append(y)
            signals.append(drive)
    if progress is not None:
        progress(n_steps)

    states = np.array(samples)
    signal_table = np.array(signals)  # (point, joint, (voltage, current, effort, error))
    recorded = pd.DataFrame(outputs, columns=physics.Outputs._fields)
    for name, signal in scenario.inputs(grid[::every], variant).items():
        recorded[name] = signal
    traces, exact = [], []
    for j, joint in enumerate(joints):
        voltage, current, effort = (signal_table[:, j, i] for i in range(3))
        # the drive's values at the communication points, held over each step, for the
        # series and the effort, current and tracking metrics; its energies are the solve's
        traces.append(DriveTrace(joint, models[j], step_size, voltage[:-1], current[:-1],
                                 effort[:-1], current, states[:, position_index[j]],
                                 states[:, speed_index[j]], scenario.reference(grid, j),
                                 np.array(enabled[j])[phase_of[:-1]]))
        first = energy_start + len(ENERGIES) * j
        cumulative = dict(zip(ENERGIES, states[:, first:first + len(ENERGIES)].T, strict=True))
        exact.append(cumulative | {"W_bond_drive": cumulative["W_link"],
                                   "W_bond_joint": cumulative["W_link"],
                                   "W_bond_error": np.zeros(len(grid))})
    return assemble(scenario, variant, model, recorded, traces,
                    {joint.name: g for joint, g in zip(joints, gains, strict=True)},
                    run_parameters(scenario, variant, models), [], exact, joint_drive_set)


def drive_signals(m: MotorParameters, g: PIDGains, drive: Sequence[float], error: float,
                  speed: float, on: bool = True) -> tuple[float, float, float]:
    """A joint's drive as a continuous system at its state (armature current i [A], the PID's
    integral [V] and filtered error [rad or m]), the tracking error (reference less
    position) and the joint's speed: (voltage [V], current [A], effort [N m or N]); a drive
    that is off gives 0 V, 0 A and no effort."""
    if not on:
        return 0.0, 0.0, 0.0
    current, integral, filtered = drive
    voltage = g.Kp * error + integral + g.Kd / g.T_f * (error - filtered)
    voltage = min(max(voltage, -m.V_supply), m.V_supply)
    return voltage, current, transmitted_effort(m, current, speed)


def drive_rates(m: MotorParameters, g: PIDGains, drive: Sequence[float], error: float,
                speed: float, on: bool = True) -> tuple[float, list[float], DriveEnergies]:
    """A joint's drive as one ODE (`drive_signals`): its effort [N m or N], the rates of its
    DRIVE_STATES (a drive that is off holds its current at 0 and its integral) and the rates
    of its energies (`drive_powers`) [W]."""
    voltage, current, effort = drive_signals(m, g, drive, error, speed, on)
    rates = [armature_rate(m, voltage, current, speed) if on else 0.0,
             g.Ki * error if on else 0.0, (error - drive[2]) / g.T_f]
    return effort, rates, drive_powers(m, voltage, current, effort, speed)


def switch_drives(x: np.ndarray, phase: int, enabled: list[tuple[bool, ...]],
                   drives: list, references: list[float], position_index: list[int],
                   n_mech: int, energy_start: int) -> np.ndarray:
    """The state at the start of a phase with the drives switched as it says: a drive
    switched off drops its current (the armature's magnetic energy goes to E_copper); one
    switched on starts its controller with the integral reset and the filtered error at the
    error (no derivative kick)."""
    x = x.copy()
    for j, on in enumerate(enabled):
        if phase == 0 or on[phase] == on[phase - 1]:
            continue
        state = n_mech + DRIVE_STATES * j
        if on[phase]:
            x[state + 1] = 0.0
            x[state + 2] = references[j] - x[position_index[j]]
        else:
            copper = energy_start + len(ENERGIES) * j + ENERGIES.index("E_copper")
            x[copper] += 0.5 * drives[j].L_a * x[state] ** 2
            x[state] = 0.0
    return x


def _input_rates(physics: ModuleType, segment: dict[str, tuple], s: float,
                 duration: float) -> tuple:
    """d/dt of the mechanism's ramped Real inputs at fraction s of a phase lasting duration
    [s] (central difference of the ramp), as its Inputs (0 for the others): masses that
    change while the mechanism moves join from rest or leave with their speed."""
    h = 1e-6
    rates = {name: (ramp(start, end, shape, s + h) - ramp(start, end, shape, s - h))
             / (2.0 * h * duration)
             for name, (start, end, shape) in segment.items()
             if name in physics.Inputs._fields and not isinstance(start, bool)}
    return physics.Inputs(**{name: rates.get(name, 0.0) for name in physics.Inputs._fields
                             if not isinstance(getattr(physics.Inputs(), name), bool)})


def _inputs(physics: ModuleType, joints: tuple, segment: dict[str, tuple], s: float,
            efforts: list[float]) -> tuple:
    """The mechanism's Inputs at fraction s of a phase (see Scenario.input_segments) with the
    drives' efforts [N m or N]."""
    values = {name: ramp(start, end, shape, s) for name, (start, end, shape) in segment.items()
              if name in physics.Inputs._fields}
    values.update((joint.effort, effort) for joint, effort in zip(joints, efforts, strict=True))
    return physics.Inputs(**values)
