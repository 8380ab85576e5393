"""The monolithic reference engine: the co-simulated system as one ODE solved by scipy's
solve_ivp.

The same equations as the co-simulation, without FMI and without sampling: the
mechanism's `derivatives` from its physics module and the drives' continuous form
(`harness.drive.continuous`): each joint's motor armature equation and the continuous-time
PID (filtered derivative) that each discrete controller approximates.
With the continuous controllers and no zero-order holds, this is the limit the
co-simulation converges to as the communication step shrinks; `harness bench` and the tests
measure that.

The drives' energies are integrated as extra states, so the run's energy metrics are exact
to the solver's tolerance (`harness.engines.stiff`: Radau). The solution is sampled at
the communication points k step_size, from which the series (every RECORD_INTERVAL) and the
effort, current and tracking metrics are read. The run is split at phase boundaries, where
the discrete inputs (locks) change; within a phase inputs are constant or ramps.
"""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np
import pandas as pd

from harness import registry
from harness.drive.continuous import ContinuousDrives
from harness.engines import stiff
from harness.engines.plan import RunPlan, physics_module, physics_parameters
from harness.engines.result import RECORD_INTERVAL, RunResult, assemble
from harness.errors import UserError
from harness.scenarios import ramp

RTOL = 1e-9       # the solver's relative tolerance (its absolute one: ATOL)
ATOL = 1e-10


def supports(model: str) -> bool:
    """Whether the monolithic reference can solve the model (a mechanism whose registration
    allows it)."""
    found = registry.registration(model)
    return found is not None and found.physics is not None and found.monolithic_reference


def run(plan: RunPlan, progress: Callable[[int], None] | None = None,
        rtol: float = RTOL) -> RunResult:
    """Solve the planned run as one ODE; its series and metrics sampled at the plan's
    communication points."""
    if not supports(plan.model):
        known = [m for m, r in registry.mechanisms().items() if r.monolithic_reference]
        raise UserError(f"no monolithic reference for model {plan.model}; known: "
                        f"{', '.join(known)}")
    physics = physics_module(plan.model)
    scenario, joints = plan.scenario, plan.scenario.joints
    p = physics_parameters(physics, plan.parameters)
    state_names = physics.State._fields
    position_index = [state_names.index(joint.position) for joint in joints]
    speed_index = [state_names.index(joint.speed) for joint in joints]
    n_mech = len(state_names)
    drives = ContinuousDrives(plan.drives, n_mech)
    x = np.array([*physics.initial_state(p), *drives.initial()])

    grid = plan.times
    every = max(1, round(RECORD_INTERVAL / plan.step_size))  # points between recorded rows
    # the phase of each point: that starting at or before it (to a nanosecond), the last
    # phase holding the task's end
    starts = [t0 for _, t0, _ in scenario.phase_times()]
    phase_of = np.searchsorted(starts, grid + 1e-9, side="right") - 1
    samples, outputs = [], []
    for k, ((phase, t0, t1), segment) in enumerate(zip(scenario.phase_times(), plan.segments,
                                                       strict=True)):
        targets = [scenario.reference_segments(j)[k][2:] for j in range(len(joints))]

        def references_at(s: float, targets=targets) -> list[float]:
            return [ramp(*target, "quintic", s) for target in targets]

        def drive_at(y: np.ndarray, s: float, k: int = k) -> tuple[list[float], list[float]]:
            """The joints' efforts and the drives' rates at fraction s of phase k."""
            return drives.rates(y, y[position_index], y[speed_index], references_at(s), k)

        x = drives.switched(x, k, references_at(0.0), x[position_index])

        def rhs(t: float, y: np.ndarray, t0=t0, t1=t1, segment=segment,
                drive_at=drive_at) -> np.ndarray:
            s = (t - t0) / (t1 - t0)
            efforts, drive_rates = drive_at(y, s)
            u = _inputs(physics, joints, segment, s, efforts)
            rates = _input_rates(physics, segment, s, t1 - t0)
            return np.array([*physics.derivatives(p, u, physics.State(*y[:n_mech]), rates),
                             *drive_rates])

        # the communication points of the phase (the last phase's end too), then its end
        points = np.clip(grid[phase_of == k], t0, t1)
        solution = stiff.solve(rhs, (t0, t1), x, rtol, ATOL,
                               t_eval=np.append(points[points < t1], t1))
        if not solution.success:
            raise RuntimeError(f"reference solve failed in phase {phase}: {solution.message}")
        x = solution.y[:, -1]
        for t, y in zip(points, solution.y.T, strict=False):  # and the end if it is a point
            if len(samples) % every == 0:  # a recorded row: the mechanism's outputs
                s = (t - t0) / (t1 - t0)
                u = _inputs(physics, joints, segment, s, drive_at(y, s)[0])
                outputs.append(physics.outputs(p, u, physics.State(*y[:n_mech])))
            samples.append(y)
    if progress is not None:
        progress(plan.n_steps)

    states = np.array(samples)
    recorded = pd.DataFrame(outputs, columns=physics.Outputs._fields)
    for name, signal in plan.inputs.items():
        recorded[name] = signal[::every]
    traces = drives.traces(states, states[:, position_index].T, states[:, speed_index].T)
    return assemble(plan, recorded, traces, [], drives.cumulative_energies(states))


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
