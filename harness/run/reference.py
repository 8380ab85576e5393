"""Monolithic reference: the co-simulated system as one ODE solved by scipy's solve_ivp.

The same equations as the co-simulation, without FMI and without sampling: the
mechanism's `derivatives` from its physics module, each joint's motor armature equation, and
the continuous-time PID (filtered derivative) that each discrete controller approximates.
With the continuous controllers and no zero-order holds, this is the limit the
co-simulation converges to as the communication step shrinks; `harness bench` and the tests
measure that.

The drives' energies are integrated as extra states, their rates those of
`fmu_src.units.drive.dc_motor.drive_powers`, the definition the co-simulation's metrics share.
The run is split at phase boundaries, where the discrete inputs (locks) change; within a phase
inputs are constant or ramps. """

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from types import ModuleType
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from fmu_src.units.drive.dc_motor import (
    DriveEnergies,
    armature_rate,
    armature_voltage,
    drive_powers,
)
from harness import registry
from harness.errors import UserError
from harness.run.controller import ControllerDesign, PIDGains, design_pid
from harness.run.drive import MotorParameters, motors
from harness.run.metrics import ENERGIES, run_metrics
from harness.run.scenario_files import Scenario, Variant, ramp

# model identifier -> its pure physics module in fmu_src, for the mechanisms it can solve
PHYSICS = {model: r.physics.__name__ for model, r in registry.mechanisms().items()
           if r.monolithic_reference}
DRIVE_STATES = 3  # per joint: armature current, PID integral, filtered error


@dataclass
class ReferenceResult:
    """Energies [J] of the monolithic run (metric names as in the co-simulation) and the
    trajectory at the solver's time points."""

    metrics: dict[str, float]
    times: np.ndarray       # solver time points [s]
    positions: np.ndarray   # joint positions at those times [rad or m], one row per joint


def physics_module(model: str) -> ModuleType:
    """The pure physics module of a mechanism the monolithic reference can solve."""
    found = registry.registration(model)
    if found is None or found.physics is None or not found.monolithic_reference:
        raise UserError(f"no monolithic reference for model {model}; "
                        f"known: {', '.join(PHYSICS)}")
    return found.physics


def parameters(physics: ModuleType, scenario: Scenario, variant: Variant,
               motor: MotorParameters | Mapping[str, MotorParameters] | None = None) -> Any:
    """The physics module's validated Parameters of a run: defaults, then the scenario's and
    the variant's values, the initial positions and the drives' reflected inertias (motor as
    in `harness.run.drive.motors`)."""
    values = {f.name: f.default for f in fields(physics.Parameters)}
    values.update(scenario.parameters)
    values.update(variant.parameters)
    drives = motors(motor)
    for joint, initial in zip(scenario.joints, scenario.initial_angle, strict=True):
        values[joint.start_parameter] = initial
        values[joint.drive_inertia] = drives[joint.motor].J_drive
    p = physics.Parameters(**values)
    physics.validate(p)
    return p


def simulate(scenario: Scenario, variant: Variant,
             motor: MotorParameters | Mapping[str, MotorParameters] | None = None,
             design: ControllerDesign = ControllerDesign(), rtol: float = 1e-9) -> ReferenceResult:
    """Solve the whole task as one ODE; returns the drive energies of docs/results.md."""
    physics = physics_module(variant.model or scenario.model)
    scenario = scenario.for_variant(variant)
    joints = scenario.joints
    drives = [motors(motor)[joint.motor] for joint in joints]
    p = parameters(physics, scenario, variant, motor)
    gains = [design_pid(m, getattr(p, joint.inertia) + m.J_drive, getattr(p, joint.friction),
                        design) for joint, m in zip(joints, drives, strict=True)]
    state_names = physics.State._fields
    position_index = [state_names.index(joint.position) for joint in joints]
    speed_index = [state_names.index(joint.speed) for joint in joints]
    n_mech, n_joints = len(state_names), len(joints)
    energy_start = n_mech + DRIVE_STATES * n_joints

    # start in equilibrium, as the co-simulation does
    mech0 = physics.initial_state(p)
    segments = scenario.input_segments(variant)
    out0 = physics.outputs(p, _inputs(physics, joints, segments[0], 0.0, [0.0] * n_joints),
                           mech0)
    x = [*mech0]
    for joint, m, i, initial in zip(joints, drives, position_index, scenario.initial_angle,
                                    strict=True):
        current = joint.hold_effort(getattr(out0, joint.static_output)) / m.torque_per_amp
        x += [current, armature_voltage(m, current, 0.0), initial - mech0[i]]
    x = np.array(x + [0.0] * (len(ENERGIES) * n_joints))
    times, positions = [0.0], [[mech0[i] for i in position_index]]

    for k, ((_, t0, t1), segment) in enumerate(zip(scenario.phase_times(), segments,
                                                   strict=True)):
        targets = [scenario.reference_segments(j)[k][2:] for j in range(n_joints)]

        def rhs(t: float, y: np.ndarray, t0=t0, t1=t1, targets=targets,
                segment=segment) -> np.ndarray:
            s = (t - t0) / (t1 - t0)
            mech = y[:n_mech]
            efforts, d_drive, d_energy = [], [], []
            for j, (m, g) in enumerate(zip(drives, gains, strict=True)):
                effort, rates, powers = drive_rates(
                    m, g, y[n_mech + DRIVE_STATES * j:n_mech + DRIVE_STATES * (j + 1)],
                    ramp(*targets[j], "quintic", s) - mech[position_index[j]],
                    mech[speed_index[j]])
                efforts.append(effort)
                d_drive += rates
                d_energy += powers
            u = _inputs(physics, joints, segment, s, efforts)
            rates = _input_rates(physics, segment, s, t1 - t0)
            return np.array([*physics.derivatives(p, u, physics.State(*mech), rates),
                             *d_drive, *d_energy])

        solution = solve_ivp(rhs, (t0, t1), x, method="Radau", rtol=rtol,
                             atol=1e-10, dense_output=False)
        if not solution.success:
            raise RuntimeError(f"reference solve failed in phase {scenario.phases[k].name}: "
                               f"{solution.message}")
        x = solution.y[:, -1]
        times.extend(solution.t[1:])
        positions.extend(solution.y[position_index, 1:].T.tolist())
    energies = x[energy_start:].reshape(n_joints, len(ENERGIES))
    per_joint = {joint.name: dict(zip(ENERGIES, row.tolist(), strict=True))
                 for joint, row in zip(joints, energies, strict=True)}
    return ReferenceResult(run_metrics(per_joint), np.array(times), np.array(positions).T)


def drive_rates(m: MotorParameters, g: PIDGains, drive: Sequence[float], error: float,
                speed: float) -> tuple[float, list[float], DriveEnergies]:
    """A joint's drive as one ODE: its effort [N m or N], the rates of its DRIVE_STATES
    (armature current i [A], the PID's integral [V] and its filtered error [rad or m]) and
    the rates of its energies (`drive_powers`) [W], for the drive's state, the tracking
    error (reference less position) and the joint's speed [rad/s or m/s]."""
    current, integral, filtered = drive
    voltage = g.Kp * error + integral + g.Kd / g.T_f * (error - filtered)
    voltage = min(max(voltage, -m.V_supply), m.V_supply)
    effort = m.torque_per_amp * current
    return (effort, [armature_rate(m, voltage, current, speed), g.Ki * error,
                     (error - filtered) / g.T_f],
            drive_powers(m, voltage, current, effort, speed))


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
