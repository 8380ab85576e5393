"""Model Exchange engine: a host solver integrates a mechanism FMU's FMI 2.0 Model Exchange
interface together with the drives' ODE (docs/model_exchange.md).

scipy's `solve_ivp` (Radau) integrates one state vector: the FMU's continuous states (the
mechanism's State, its energy account included), then per joint the motor's armature
current, the continuous PID's integral and filtered error and the drive's energies, with the
rates the monolithic reference (`harness.engines.reference`) gives the drives
(`reference.drive_rates`) and the FMU's derivatives for the mechanism. A drive the scenario
switches off for a phase (`Scenario.drive_enabled`) is switched as the reference switches it
(`switch_drives`). There is no coupling step: the solver sees the whole system at once, as a
Modelica tool with the FMU embedded would.

Events. The FMU's event indicators are solve_ivp's terminal events (located just past zero,
by EVENT_MARGIN, so that the FMU's event update finds them crossed); at each, the FMU enters
event mode and settles (a stop's impact, a slider sticking), and the solver starts again from
the state it gives. The scenario's discrete inputs (locks, payload) change at the phase
boundaries; one that ramps (a payload caught over 3 s) changes as a staircase, a step every
`step_size`, as the co-simulation master sets it: each change is an event.

The result is every engine's (`harness.engines.result.assemble`): the FMU's outputs every
RECORD_INTERVAL and each drive's trace sampled every step_size (voltage and current at the
step's start, the current averaged over it), with the drives' energies the integrals the
solver computes without sampling (`exact`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from fmu_src.units.drive.dc_motor import armature_voltage, transmitted_effort
from harness.drive.controller import ControllerDesign
from harness.drive.metrics import ENERGIES
from harness.drive.trace import DriveTrace
from harness.engines import DEFAULT_STEP
from harness.engines.reference import DRIVE_STATES, drive_rates, drive_signals, switch_drives
from harness.engines.result import RunResult, assemble, recorded_points
from harness.engines.setup import (
    Drives,
    Motors,
    enabled_steps,
    joint_drive,
    joint_drives,
    run_parameters,
)
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.model_exchange import ModelExchangeFMU
from harness.fmu.models import check_names
from harness.scenarios import Scenario, Variant

RELATIVE_TOLERANCE = 1e-8
ABSOLUTE_TOLERANCE = 1e-10
# how far past zero [the indicator's unit] an event indicator is located: the FMU's event
# update acts on a crossed indicator (a state beyond a stop, a speed past zero)
EVENT_MARGIN = 1e-10


def supports(model: str) -> bool:
    """Whether the model's FMU offers Model Exchange (the mechanisms do)."""
    from fmpy import read_model_description
    return read_model_description(str(fmu_build.locate(model))).modelExchange is not None


def run(scenario: Scenario, variant: Variant, step_size: float = DEFAULT_STEP,
        progress: Callable[[int], None] | None = None, motor: Motors = None,
        design: ControllerDesign = ControllerDesign(), rtol: float = RELATIVE_TOLERANCE,
        drives: Drives = None) -> RunResult:
    """Run one variant of a scenario with the mechanism as Model Exchange (module
    docstring); step_size [s]: the interval of the recorded drive traces and of a ramped
    discrete input's staircase; progress(steps): told the steps done; drives: each joint's
    drive by name, else motor's legacy drives (`harness.engines.setup.joint_drives`)."""
    if not (step_size > 0.0 and np.isfinite(step_size)):
        raise UserError(f"step size = {step_size} s is outside (0, inf)")
    scenario = scenario.for_variant(variant)
    joints = scenario.joints
    joint_drive_set = joint_drives(scenario, motor, drives)
    models = [drive.parameters for drive in joint_drive_set]
    model = variant.model or scenario.model
    parameters = run_parameters(scenario, variant, models)
    check_names(scenario, variant, parameters)
    n_steps = round(scenario.duration / step_size)
    grid = np.arange(n_steps + 1) * step_size
    segments = scenario.input_segments(variant)
    with ModelExchangeFMU(fmu_build.locate(model), f"{scenario.name}.{variant.name}") as fmu:
        discrete = {name for name in segments[0]
                    if fmu.variables[name].variability == "discrete"}
        x = fmu.initialize(parameters, scenario.inputs_at(0.0, segments), scenario.duration)
        enabled = [scenario.drive_enabled(j) for j in range(len(joints))]
        gains, y = {}, [*x]
        for j, (joint, m) in enumerate(zip(joints, models, strict=True)):
            values = fmu.get([joint.inertia, joint.friction, joint.static_output])
            gains[joint.name], current = joint_drive(values, joint, m, design)
            current = current if enabled[j][0] else 0.0  # off from the start: nothing held
            y += [current, armature_voltage(m, current, 0.0), 0.0]
        system = _System(fmu, scenario, segments, discrete, joints, models,
                         [gains[j.name] for j in joints], enabled, grid,
                         recorded_points(grid, step_size))
        y = np.array(y + [0.0] * (len(ENERGIES) * len(joints)))
        system.sample(0.0, 0.0, y, lambda times: np.array([y]))
        done = 0
        for a, b in _intervals(scenario, segments, discrete, step_size):
            y = system.integrate(a, b, y, rtol)
            if progress is not None:
                reached = min(round(b / step_size), n_steps)
                progress(reached - done)
                done = reached
        messages = [f"{m.status}: {m.message}" for m in fmu.messages]
    samples = system.samples
    traces = [system.trace(j, grid, samples, step_size) for j in range(len(joints))]
    return assemble(scenario, variant, model, pd.DataFrame(system.records), traces,
                    gains, parameters, messages, system.cumulative_energies(),
                    joint_drive_set)


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
                 enabled: list[tuple[bool, ...]], grid: np.ndarray,
                 recorded: np.ndarray) -> None:
        self.fmu, self.scenario, self.segments = fmu, scenario, segments
        self.discrete, self.joints, self.drives, self.gains = discrete, joints, drives, gains
        self.enabled = enabled
        self.starts = [t0 for _, t0, _ in scenario.phase_times()]
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
        phase = self.phase_at(t)
        d_drive, d_energy = [], []
        for j, joint in enumerate(self.joints):
            start = self.nx + DRIVE_STATES * j
            effort, rates, powers = drive_rates(
                self.drives[j], self.gains[j], y[start:start + DRIVE_STATES],
                reference[j] - y[self.position[j]], y[self.speed[j]], self.enabled[j][phase])
            inputs[joint.effort] = effort
            d_drive += rates
            d_energy += powers
        return inputs, d_drive, d_energy

    def phase_at(self, t: float) -> int:
        """The phase that holds t (a time a nanosecond short of a phase start counts as that
        start)."""
        return max(0, int(np.searchsorted(self.starts, t + 1e-9, side="right")) - 1)

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
        phase = self.phase_at(a)
        if abs(a - self.starts[phase]) < 1e-9:  # a phase start: the drives switch as it says
            y = switch_drives(y, phase, self.enabled, self.drives,
                              list(self.scenario.reference_at(a)), self.position, self.nx,
                              self.energy_start)
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
        averaged over it (trapezoid), the effort it gives at the speed then."""
        m, g, joint = self.drives[j], self.gains[j], self.joints[j]
        start = self.nx + DRIVE_STATES * j
        reference = np.array([self.scenario.reference_at(float(t))[j] for t in grid])
        error = reference - samples[:, self.position[j]]
        on = np.array(enabled_steps(self.scenario, j, grid), dtype=bool)
        voltage = np.array([drive_signals(m, g, state, e, 0.0, o)[0] for state, e, o in zip(
            samples[:-1, start:start + DRIVE_STATES], error[:-1], on, strict=True)])
        current = samples[:, start]
        average = np.where(on, 0.5 * (current[:-1] + current[1:]), 0.0)
        speed = samples[:, self.speed[j]]
        return DriveTrace(joint, m, step_size, voltage, average,
                          transmitted_effort(m, average, speed[:-1]), current,
                          samples[:, self.position[j]], speed, reference, on)

    def cumulative_energies(self) -> list[dict[str, np.ndarray]]:
        """Per joint, the drives' energies the solver integrated up to every grid point [J]
        (ENERGIES, and the power bond's, whose coupling error is none)."""
        out = []
        for j in range(len(self.joints)):
            first = self.energy_start + len(ENERGIES) * j
            cumulative = dict(zip(ENERGIES, self.samples[:, first:first + len(ENERGIES)].T,
                                  strict=True))
            out.append(cumulative | {"W_bond_drive": cumulative["W_link"],
                                     "W_bond_joint": cumulative["W_link"],
                                     "W_bond_error": np.zeros(len(self.grid))})
        return out
