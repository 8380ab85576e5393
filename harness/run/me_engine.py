"""Model Exchange engine: a host solver integrates a mechanism FMU's FMI 2.0 Model Exchange
interface together with the drives' ODE (docs/model_exchange.md).

scipy's `solve_ivp` (Radau) integrates one state vector: the FMU's continuous states (the
mechanism's State, its energy account included), then per joint the motor's armature current,
the continuous PID's integral and filtered error and the drive's energies, with the rates the
monolithic reference (`harness.run.reference`) gives the drives (`reference.drive_rates`) and
the FMU's derivatives for the mechanism. There is no coupling step: the solver sees the whole
system at once, as a Modelica tool with the FMU embedded would.

Events. The FMU's event indicators are solve_ivp's terminal events (located just past zero,
by EVENT_MARGIN, so that the FMU's event update finds them crossed); at each, the FMU enters
event mode and settles (a stop's impact, a slider sticking), and the solver starts again from
the state it gives. The scenario's discrete inputs (locks, payload) change at the phase
boundaries; one that ramps (a payload caught over 3 s) changes as a staircase, a step every
`step_size`, as the co-simulation master sets it: each change is an event.

The result is the master's (`harness.run.master.assemble`): the FMU's outputs every
RECORD_INTERVAL and each drive's trace sampled every step_size (voltage and current at the
step's start, the current averaged over it), with the drives' energies replaced by their
integrals, which the solver computes without sampling.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from fmu_src.units.drive.dc_motor import armature_voltage
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.model_exchange import ModelExchangeFMU
from harness.run import master, metrics
from harness.run.controller import ControllerDesign
from harness.run.drive import DriveTrace, MotorParameters, motors
from harness.run.reference import DRIVE_STATES, drive_rates
from harness.run.scenario_files import Scenario, Variant

RELATIVE_TOLERANCE = 1e-8
ABSOLUTE_TOLERANCE = 1e-10
# how far past zero [the indicator's unit] an event indicator is located: the FMU's event
# update acts on a crossed indicator (a state beyond a stop, a speed past zero)
EVENT_MARGIN = 1e-10


def run(scenario: Scenario, variant: Variant, step_size: float = master.DEFAULT_STEP, *,
        progress: Callable[[int], None] | None = None,
        motor: MotorParameters | Mapping[str, MotorParameters] | None = None,
        design: ControllerDesign = ControllerDesign(),
        rtol: float = RELATIVE_TOLERANCE) -> master.RunResult:
    """Run one variant of a scenario with the mechanism as Model Exchange (module
    docstring); step_size [s]: the interval of the recorded drive traces and of a ramped
    discrete input's staircase; progress(k): told the step k reached."""
    if not (step_size > 0.0 and np.isfinite(step_size)):
        raise UserError(f"step size = {step_size} s is outside (0, inf)")
    scenario = scenario.for_variant(variant)
    joints = scenario.joints
    drives = [motors(motor)[joint.motor] for joint in joints]
    model = variant.model or scenario.model
    parameters = master.run_parameters(scenario, variant, drives)
    master.check_names(scenario, variant, parameters)
    n_steps = round(scenario.duration / step_size)
    grid = np.arange(n_steps + 1) * step_size
    segments = scenario.input_segments(variant)
    with ModelExchangeFMU(fmu_build.locate(model), f"{scenario.name}.{variant.name}") as fmu:
        discrete = {name for name in segments[0]
                    if fmu.variables[name].variability == "discrete"}
        x = fmu.initialize(parameters, scenario.inputs_at(0.0, segments), scenario.duration)
        gains, y = {}, [*x]
        for joint, m in zip(joints, drives, strict=True):
            gains[joint.name], current = master.joint_drive(fmu, joint, m, design)
            y += [current, armature_voltage(m, current, 0.0), 0.0]
        system = _System(fmu, scenario, segments, discrete, joints, drives,
                         [gains[j.name] for j in joints], grid,
                         master.recorded_points(grid, step_size))
        y = np.array(y + [0.0] * (len(metrics.ENERGIES) * len(joints)))
        system.sample(0.0, 0.0, y, lambda times: np.array([y]))
        for a, b in _intervals(scenario, segments, discrete, step_size):
            y = system.integrate(a, b, y, rtol)
            if progress is not None:
                progress(min(round(b / step_size), n_steps))
        messages = [f"{m.status}: {m.message}" for m in fmu.messages]
    samples = system.samples
    traces = [system.trace(j, grid, samples, step_size) for j in range(len(joints))]
    result = master.assemble(scenario, variant, model, pd.DataFrame(system.records), traces,
                             gains, parameters, messages)
    result.metrics.update(system.integrated_energies(y))
    return result


def _intervals(scenario: Scenario, segments: list[dict], discrete: set[str],
               step_size: float) -> list[tuple[float, float]]:
    """The intervals over which the discrete inputs are held: each phase, cut into steps of
    step_size where one of them ramps."""
    out = []
    for (_, t0, t1), segment in zip(scenario.phase_times(), segments, strict=True):
        ramps = any(start != end for name, (start, end, _) in segment.items()
                    if name in discrete)
        n = max(1, round((t1 - t0) / step_size)) if ramps else 1
        out += [(t0 + (t1 - t0) * k / n, t0 + (t1 - t0) * (k + 1) / n) for k in range(n)]
    return out


class _System:
    """The FMU and the drives as one ODE for solve_ivp."""

    def __init__(self, fmu: ModelExchangeFMU, scenario: Scenario, segments: list[dict],
                 discrete: set[str], joints: tuple, drives: list, gains: list,
                 grid: np.ndarray, recorded: np.ndarray) -> None:
        self.fmu, self.scenario, self.segments = fmu, scenario, segments
        self.discrete, self.joints, self.drives, self.gains = discrete, joints, drives, gains
        # the state at each point of the grid, and the FMU's outputs at the recorded ones
        self.grid, self.samples = grid, np.zeros((len(grid), 0))
        self.recorded = np.zeros(len(grid), dtype=bool)
        self.recorded[recorded] = True
        self.records: list[dict[str, float]] = []
        self.outputs = [v.name for v in fmu.model_description.modelVariables
                        if v.causality == "output"]
        self.nx = fmu.nx
        derivatives = fmu.model_description.derivatives
        state_names = [d.variable.derivative.name for d in derivatives]
        self.position = [state_names.index(j.position) for j in joints]
        self.speed = [state_names.index(j.speed) for j in joints]
        self.energy_start = self.nx + DRIVE_STATES * len(joints)
        self.events = [self._event(i) for i in range(fmu.nz)]

    def _continuous_inputs(self, t: float, y: np.ndarray) -> tuple[dict, list, list]:
        """The FMU's continuous inputs at (t, y): the efforts and the scenario's continuous
        inputs; and each drive's rates and energy rates."""
        reference = self.scenario.reference_at(t)
        inputs = {name: value for name, value in self.scenario.inputs_at(
            t, self.segments).items() if name not in self.discrete}
        d_drive, d_energy = [], []
        for j, joint in enumerate(self.joints):
            start = self.nx + DRIVE_STATES * j
            effort, rates, powers = drive_rates(
                self.drives[j], self.gains[j], y[start:start + DRIVE_STATES],
                reference[j] - y[self.position[j]], y[self.speed[j]])
            inputs[joint.effort] = effort
            d_drive += rates
            d_energy += powers
        return inputs, d_drive, d_energy

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        inputs, d_drive, d_energy = self._continuous_inputs(t, y)
        self.fmu.evaluate(t, y[:self.nx], inputs)
        return np.concatenate([self.fmu.derivatives(), d_drive, d_energy])

    def _event(self, i: int) -> Callable[[float, np.ndarray], float]:
        def indicator(t: float, y: np.ndarray) -> float:
            self.fmu.evaluate(t, y[:self.nx], self._continuous_inputs(t, y)[0])
            return float(self.fmu.indicators()[i]) + EVENT_MARGIN
        indicator.terminal, indicator.direction = True, -1.0
        return indicator

    def sample(self, t: float, end: float, y: np.ndarray,
               solution: Callable[[np.ndarray], np.ndarray]) -> None:
        """The grid's points in (t, end] (and 0 at the start) from the solution's dense
        output, and the FMU's outputs at the recorded ones among them, in time order (before
        the event at end, if any)."""
        if not self.samples.size:
            self.samples = np.zeros((len(self.grid), len(y)))
        inside = np.flatnonzero((self.grid > t) & (self.grid <= end)) if end > 0.0 else [0]
        if not len(inside):
            return
        values = solution(self.grid[inside])
        self.samples[inside] = values
        for k, state in zip(inside, values, strict=True):
            if self.recorded[k]:
                time = float(self.grid[k])
                self.fmu.evaluate(time, state[:self.nx], self._continuous_inputs(time, state)[0])
                self.records.append({**self.fmu.get(self.outputs),
                                     **self.scenario.inputs_at(time, self.segments)})

    def integrate(self, a: float, b: float, y: np.ndarray, rtol: float) -> np.ndarray:
        """From a to b [s]: the discrete inputs of a set in an event at a, then solve_ivp
        restarted at each state event; the grid's points in (a, b] sampled."""
        held = {name: value for name, value in self.scenario.inputs_at(a, self.segments).items()
                if name in self.discrete}
        y = y.copy()
        y[:self.nx] = self.fmu.event(a, y[:self.nx], held)
        t = a
        while t < b:
            solution = solve_ivp(self.rhs, (t, b), y, method="Radau", rtol=rtol,
                                 atol=ABSOLUTE_TOLERANCE, events=self.events or None,
                                 dense_output=True)
            if not solution.success:
                raise RuntimeError(f"Model Exchange solve failed at t = {t} s: "
                                   f"{solution.message}")
            end = solution.t[-1]
            self.sample(t, end, y, lambda times, dense=solution.sol: dense(times).T)
            y = solution.y[:, -1].copy()
            t = end
            self.fmu.evaluate(t, y[:self.nx], self._continuous_inputs(t, y)[0])
            if solution.status == 1 or self.fmu.completed_step():   # a state event
                y[:self.nx] = self.fmu.event(t, y[:self.nx], {})
        return y

    def trace(self, j: int, grid: np.ndarray, samples: np.ndarray, step_size: float
              ) -> DriveTrace:
        """Joint j's drive sampled every step: voltage at each step's start, the current
        averaged over it (trapezoid), the effort it gives."""
        m, g, joint = self.drives[j], self.gains[j], self.joints[j]
        start = self.nx + DRIVE_STATES * j
        current = samples[:, start]
        reference = np.array([self.scenario.reference_at(float(t))[j] for t in grid])
        error = reference - samples[:, self.position[j]]
        voltage = np.clip(g.Kp * error + samples[:, start + 1]
                          + g.Kd / g.T_f * (error - samples[:, start + 2]),
                          -m.V_supply, m.V_supply)[:-1]
        average = 0.5 * (current[:-1] + current[1:])
        return DriveTrace(joint, m, step_size, voltage, average, m.torque_per_amp * average,
                          current, samples[:, self.position[j]], samples[:, self.speed[j]],
                          reference)

    def integrated_energies(self, y: np.ndarray) -> dict[str, float]:
        """The drives' energies integrated by the solver [J], as the run's metrics name them."""
        energies = y[self.energy_start:].reshape(len(self.joints), len(metrics.ENERGIES))
        per_joint = {joint.name: dict(zip(metrics.ENERGIES, row.tolist(), strict=True))
                     for joint, row in zip(self.joints, energies, strict=True)}
        return metrics.run_metrics(per_joint)
