"""Monolithic reference: the co-simulated system as one ODE solved by scipy's solve_ivp.

The same equations as the co-simulation, without FMI and without sampling: the
mechanism's `derivatives` from its physics module, the motor's armature equation, and the
continuous-time PID (filtered derivative) that the discrete controller approximates. With
the continuous controller and no zero-order holds, this is the limit the co-simulation
converges to as the communication step shrinks; `harness bench` and the tests measure that.

The drive's energies are integrated as extra states. The run is split at phase boundaries,
where the discrete inputs (locks) change; within a phase inputs are constant or ramps.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, fields
from types import ModuleType
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from harness.controller import ControllerDesign, design_pid
from harness.drive import MotorParameters
from harness.scenarios import RAMP_SHAPES, Scenario, Variant, quintic

# model identifier -> its pure physics module in fmu_src
PHYSICS = {"SelfRegulatingBalancer": "fmu_src.self_regulating",
           "CiupituBalancer": "fmu_src.ciupitu"}
ENERGIES = ("E_in", "E_drawn", "E_copper", "E_mech", "W_link")


@dataclass
class ReferenceResult:
    """Energies [J] of the monolithic run and its trajectory at the phase ends."""

    metrics: dict[str, float]
    times: np.ndarray   # solver time points [s]
    angle: np.ndarray   # joint angle at those times [rad]


def physics_module(model: str) -> ModuleType:
    """The pure physics module of an FMU model."""
    try:
        return importlib.import_module(PHYSICS[model])
    except KeyError:
        raise ValueError(f"no monolithic reference for model {model}; "
                         f"known: {', '.join(PHYSICS)}") from None


def parameters(physics: ModuleType, scenario: Scenario, variant: Variant,
               motor: MotorParameters = MotorParameters()) -> Any:
    """The physics module's validated Parameters of a run: defaults, then the scenario's and
    the variant's values, the initial angle and the drive's reflected inertia."""
    joint = scenario.joint
    values = {f.name: f.default for f in fields(physics.Parameters)}
    values.update(scenario.parameters)
    values.update(variant.parameters)
    values[joint["initial_angle"]] = scenario.initial_angle
    values[joint["drive_inertia"]] = motor.J_drive
    p = physics.Parameters(**values)
    physics.validate(p)
    return p


def simulate(scenario: Scenario, variant: Variant, motor: MotorParameters = MotorParameters(),
             design: ControllerDesign = ControllerDesign(), rtol: float = 1e-9) -> ReferenceResult:
    """Solve the whole task as one ODE; returns the drive energies of SPEC section 7."""
    physics = physics_module(variant.model or scenario.model)
    joint = scenario.joint
    p = parameters(physics, scenario, variant, motor)
    gains = design_pid(motor, getattr(p, joint["inertia"]) + motor.J_drive,
                       getattr(p, joint["friction"]), design)
    state_names = physics.State._fields
    angle_index = state_names.index(joint["angle"])
    speed_index = state_names.index(joint["speed"])
    n_mech = len(state_names)
    k_tau, k_e = motor.torque_per_amp, motor.back_emf_per_link_speed

    # start in equilibrium, as the co-simulation does
    mech0 = physics.initial_state(p)
    segments = scenario.input_segments(variant)
    tau_gravity0 = physics.outputs(p, _phase_inputs(physics, segments[0], 0.0, 0.0),
                                   mech0).tau_gravity
    i0 = -tau_gravity0 / k_tau
    x = np.array([*mech0, i0, i0 * motor.R_a, scenario.initial_angle - mech0[angle_index],
                  *np.zeros(len(ENERGIES))])
    times, angles = [0.0], [mech0[angle_index]]
    start_angle = scenario.initial_angle

    for (_, t0, t1), phase, segment in zip(scenario.phase_times(), scenario.phases, segments,
                                           strict=True):
        a0, a1 = start_angle, phase.target

        def rhs(t: float, y: np.ndarray, t0=t0, t1=t1, a0=a0, a1=a1,
                segment=segment) -> np.ndarray:
            s = (t - t0) / (t1 - t0)
            reference = a0 + (a1 - a0) * float(quintic(np.float64(s)))
            mech, current, integral, filtered = y[:n_mech], y[n_mech], y[n_mech + 1], y[n_mech + 2]
            error = reference - mech[angle_index]
            voltage = (gains.Kp * error + integral
                       + gains.Kd / gains.T_f * (error - filtered))
            voltage = min(max(voltage, -motor.V_supply), motor.V_supply)
            omega = mech[speed_index]
            torque = k_tau * current
            u = _phase_inputs(physics, segment, s, torque)
            d_mech = physics.derivatives(p, u, physics.State(*mech))
            power = voltage * current
            return np.array([
                *d_mech,
                (voltage - motor.R_a * current - k_e * omega) / motor.L_a,
                gains.Ki * error,
                (error - filtered) / gains.T_f,
                power, max(power, 0.0), motor.R_a * current ** 2, abs(torque * omega),
                torque * omega])

        solution = solve_ivp(rhs, (t0, t1), x, method="Radau", rtol=rtol,
                             atol=1e-10, dense_output=False)
        if not solution.success:
            raise RuntimeError(f"reference solve failed in phase {phase.name}: "
                               f"{solution.message}")
        x = solution.y[:, -1]
        times.extend(solution.t[1:])
        angles.extend(solution.y[angle_index, 1:])
        start_angle = phase.target
    energies = dict(zip(ENERGIES, x[-len(ENERGIES):].tolist(), strict=True))
    return ReferenceResult(energies, np.array(times), np.array(angles))


def _phase_inputs(physics: ModuleType, segment: dict[str, tuple], s: float,
                  torque: float) -> tuple:
    """The mechanism's Inputs at fraction s of a phase (see Scenario.input_segments)."""
    values = {name: (start if start == end else start + (end - start) * RAMP_SHAPES[shape](s))
              for name, (start, end, shape) in segment.items() if name in physics.Inputs._fields}
    return physics.Inputs(**values)._replace(tau_drive=torque)
