"""Model Exchange engine: a host solver integrates a mechanism FMU's FMI 2.0 Model Exchange
interface together with the drives' ODE (docs/model_exchange.md).

scipy's Radau (`harness.engines.stiff`) integrates one state vector: the FMU's continuous
states (the mechanism's State, its energy account included), then the drives' continuous
form (`harness.drive.continuous`: per joint the motor's armature current, the continuous
PID's integral and filtered error and the drive's energies), the monolithic reference's, with
the FMU's derivatives for the mechanism. There is no coupling step: the solver sees the whole
system at once, as a Modelica tool with the FMU embedded would.

Events. The FMU's event indicators are solve_ivp's terminal events (located just past zero,
by EVENT_MARGIN, so that the FMU's event update finds them crossed); at each, the FMU enters
event mode and settles (a stop's impact, a slider sticking), and the solver starts again from
the state it gives. The scenario's discrete inputs (locks, payload) change at the phase
boundaries; one that ramps (a payload caught over 3 s) changes as a staircase, a step every
`step_size`, as the co-simulation master sets it: each change is an event.

The result is every engine's (`harness.engines.result.assemble`): the FMU's outputs every
RECORD_INTERVAL and each drive's trace sampled at the communication points
(`ContinuousDrives.traces`), with the drives' energies the integrals the solver computes
without sampling.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from harness.drive.continuous import ContinuousDrives
from harness.engines import stiff
from harness.engines.plan import RunPlan
from harness.engines.result import RunResult, assemble, recorded_points
from harness.fmu import build as fmu_build
from harness.fmu.model_exchange import ModelExchangeFMU

RELATIVE_TOLERANCE = 1e-8
ABSOLUTE_TOLERANCE = 1e-10
# how far past zero [the indicator's unit] an event indicator is located: the FMU's event
# update acts on a crossed indicator (a state beyond a stop, a speed past zero)
EVENT_MARGIN = 1e-10


def supports(model: str) -> bool:
    """Whether the model's FMU offers Model Exchange (the mechanisms do)."""
    from fmpy import read_model_description
    return read_model_description(str(fmu_build.locate(model))).modelExchange is not None


def run(plan: RunPlan, progress: Callable[[int], None] | None = None,
        rtol: float = RELATIVE_TOLERANCE) -> RunResult:
    """Run one planned run with the mechanism as Model Exchange (module docstring): the
    plan's step is the interval of the recorded drive traces and of a ramped discrete input's
    staircase; progress(steps): told the steps done."""
    scenario = plan.scenario
    with ModelExchangeFMU(fmu_build.locate(plan.model), plan.name) as fmu:
        discrete = {name for name in plan.segments[0]
                    if fmu.variables[name].variability == "discrete"}
        x = fmu.initialize(plan.parameters, scenario.inputs_at(0.0, plan.segments),
                           scenario.duration)
        system = _System(fmu, plan, discrete)
        y = np.array([*x, *system.drives.initial()])
        system.sample(0.0, 0.0, y, lambda times: np.array([y]))
        done = 0
        for a, b in _intervals(plan, discrete):
            y = system.integrate(a, b, y, rtol)
            if progress is not None:
                reached = min(round(b / plan.step_size), plan.n_steps)
                progress(reached - done)
                done = reached
        messages = [f"{m.status}: {m.message}" for m in fmu.messages]
    samples = system.samples
    traces = system.drives.traces(samples, samples[:, system.position].T,
                                  samples[:, system.speed].T)
    return assemble(plan, pd.DataFrame(system.records), traces, messages,
                    system.drives.cumulative_energies(samples))


def _intervals(plan: RunPlan, discrete: set[str]) -> list[tuple[float, float]]:
    """The intervals over which the discrete inputs are held: each phase, cut into steps of
    the plan's step where one of them ramps."""
    out = []
    for (_, t0, t1), segment in zip(plan.scenario.phase_times(), plan.segments, strict=True):
        ramps = any(start != end for name, (start, end, _) in segment.items()
                    if name in discrete)
        n = max(1, round((t1 - t0) / plan.step_size)) if ramps else 1
        out += [(t0 + (t1 - t0) * k / n, t0 + (t1 - t0) * (k + 1) / n) for k in range(n)]
    return out


class _System:
    """The FMU and the drives as one ODE for the solver."""

    def __init__(self, fmu: ModelExchangeFMU, plan: RunPlan, discrete: set[str]) -> None:
        self.fmu, self.plan, self.discrete = fmu, plan, discrete
        self.scenario, self.segments = plan.scenario, plan.segments
        self.starts = [t0 for _, t0, _ in plan.scenario.phase_times()]
        # the state at each point of the grid, and the FMU's outputs at the recorded ones
        self.grid, self.samples = plan.times, np.zeros((len(plan.times), 0))
        self.recorded = np.zeros(len(self.grid), dtype=bool)
        self.recorded[recorded_points(self.grid, plan.step_size)] = True
        self.records: list[dict[str, float]] = []
        self.outputs = [v.name for v in fmu.model_description.modelVariables
                        if v.causality == "output"]
        self.nx = fmu.nx
        state_names = [d.variable.derivative.name for d in fmu.model_description.derivatives]
        joints = plan.scenario.joints
        self.position = [state_names.index(j.position) for j in joints]
        self.speed = [state_names.index(j.speed) for j in joints]
        self.drives = ContinuousDrives(plan.drives, self.nx)
        self.events = [self._event(i) for i in range(fmu.nz)]

    def _continuous_inputs(self, t: float, y: np.ndarray) -> tuple[dict, list]:
        """The FMU's continuous inputs at (t, y): the efforts and the scenario's continuous
        inputs; and the drives' rates."""
        inputs = {name: value for name, value in self.scenario.inputs_at(
            t, self.segments).items() if name not in self.discrete}
        efforts, rates = self.drives.rates(y, y[self.position], y[self.speed],
                                           self.scenario.reference_at(t), self.phase_at(t))
        inputs.update((joint.effort, effort)
                      for joint, effort in zip(self.scenario.joints, efforts, strict=True))
        return inputs, rates

    def phase_at(self, t: float) -> int:
        """The phase that holds t (a time a nanosecond short of a phase start counts as that
        start)."""
        return max(0, int(np.searchsorted(self.starts, t + 1e-9, side="right")) - 1)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        inputs, drive_rates = self._continuous_inputs(t, y)
        self.fmu.evaluate(t, y[:self.nx], inputs)
        return np.concatenate([self.fmu.derivatives(), drive_rates])

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
        """From a to b [s]: the discrete inputs of a set in an event at a, then the solve
        restarted at each state event; the grid's points in (a, b] sampled."""
        held = {name: value for name, value in self.scenario.inputs_at(a, self.segments).items()
                if name in self.discrete}
        phase = self.phase_at(a)
        if abs(a - self.starts[phase]) < 1e-9:  # a phase start: the drives switch as it says
            y = self.drives.switched(y, phase, self.scenario.reference_at(a), y[self.position])
        y = y.copy()
        y[:self.nx] = self.fmu.event(a, y[:self.nx], held)
        t = a
        while t < b:
            solution = stiff.solve(self.rhs, (t, b), y, rtol, ABSOLUTE_TOLERANCE,
                                   events=self.events or None, dense_output=True)
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
