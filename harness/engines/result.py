"""What every engine returns: one `RunResult` per run (the series recorded every
RECORD_INTERVAL, the metrics and the design used), and `assemble`, which makes it from the
mechanism's recorded variables and each joint's `DriveTrace`, whatever engine ran it, so that
every engine writes the same result files (docs/results.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from fmu_src.units.controller.pid import PIDGains
from harness.drive import metrics
from harness.drive.motor import JointDrive
from harness.drive.trace import DriveTrace
from harness.engines.plan import RunPlan
from harness.scenarios import Joint, Scenario

RECORD_INTERVAL = 0.01    # CSV sampling interval [s] (100 Hz)


@dataclass
class RunResult:
    """One run of a scenario variant by any engine: decimated series, metrics and the design
    used."""

    scenario: str
    variant: str
    model: str
    step_size: float
    series: pd.DataFrame
    metrics: dict[str, float]
    gains: dict[str, PIDGains]      # by joint name
    parameters: dict[str, float | bool]
    joint_phase_work: dict[str, dict[str, float]] = field(default_factory=dict)
    messages: list[str] = field(default_factory=list)
    traces: list[DriveTrace] = field(default_factory=list)  # per joint, if run kept them
    drives: dict[str, JointDrive] = field(default_factory=dict)  # by joint name

    @property
    def phase_work(self) -> dict[str, float]:
        """Net work of the drives on the mechanism in each phase [J], summed over joints."""
        works = list(self.joint_phase_work.values())
        return {phase: sum(w[phase] for w in works) for phase in works[0]} if works else {}


def suffix(scenario: Scenario, joint: Joint) -> str:
    """Suffix of a joint's drive columns and metrics: none with one joint, else _<joint>."""
    return "" if len(scenario.joints) == 1 else f"_{joint.name}"


def assemble(plan: RunPlan, recorded: pd.DataFrame, traces: list[DriveTrace],
             messages: list[str], exact: list[dict[str, np.ndarray]] | None = None
             ) -> RunResult:
    """A RunResult of a run's plan from its records, whatever engine produced them.

    recorded: the mechanism's variables recorded every RECORD_INTERVAL from t = 0, one row
    each; traces: each joint's drive over the run, in the scenario's joint order. exact: per
    joint, its energies (ENERGIES and BOND of `harness.drive.metrics`) integrated up to every
    communication point by an engine that solves them [J], which replace those the trace's
    held values give (a continuous solver's). Each joint's drive is reported with its metrics
    (`harness.drive.metrics.drive_report`).
    """
    scenario, drives = plan.scenario, plan.joint_drives
    first = traces[0]
    times = first.times
    rows = recorded_points(times, first.step_size)[:len(recorded)]
    series = recorded.reset_index(drop=True)
    series.insert(0, "time", times[rows])
    per_joint, joint_phase_work = {}, {}
    phases = [(name, point_at(times, first.step_size, t0), point_at(times, first.step_size, t1))
              for name, t0, t1 in scenario.phase_times()]
    for j, (joint, trace) in enumerate(zip(scenario.joints, traces, strict=True)):
        if exact is None:
            energies = trace.energies()
            per_step = {"E_in": energies.E_in, "E_drawn": energies.E_drawn,
                        **dict(zip(metrics.BOND, metrics.bond_energies(trace, energies),
                                   strict=True))}
            cumulative = {name: np.concatenate([[0.0], np.cumsum(values)])
                          for name, values in per_step.items()}
            per_joint[joint.name] = metrics.drive_metrics(trace)
            joint_phase_work[joint.name] = {name: float(np.sum(energies.W_link[k0:k1]))
                                            for name, k0, k1 in phases}
        else:
            cumulative = exact[j]
            per_joint[joint.name] = metrics.drive_metrics(trace) | {
                name: float(cumulative[name][-1]) for name in (*metrics.ENERGIES, *metrics.BOND)}
            joint_phase_work[joint.name] = {
                name: float(cumulative["W_link"][k1] - cumulative["W_link"][k0])
                for name, k0, k1 in phases}
        per_joint[joint.name] = metrics.drive_report(drives[j], per_joint[joint.name])
        _add_drive_columns(series, trace, cumulative, suffix(scenario, joint), rows)
    if len(scenario.joints) > 1:
        _add_total_columns(series, [suffix(scenario, joint) for joint in scenario.joints])
    for column in series.columns:
        if series[column].dtype == bool:
            series[column] = series[column].astype(int)
    run_metrics = metrics.run_metrics(per_joint)
    step_size = first.step_size
    if np.ndim(step_size) != 0:  # variable steps: the mean step, their number, the events
        run_metrics |= {"steps": len(step_size),
                        "event_lag_max": event_lag(times, scenario.phase_times())}
        step_size = float(times[-1] / len(step_size))
    return RunResult(scenario.name, plan.variant.name, plan.model, step_size, series,
                     run_metrics, plan.gains, plan.parameters, joint_phase_work, messages,
                     drives=dict(zip([joint.name for joint in scenario.joints], drives,
                                     strict=True)))


def recorded_points(times: np.ndarray, step_size: float | np.ndarray) -> np.ndarray:
    """The communication points a run records (indexes into times [s]): every
    RECORD_INTERVAL from t = 0; with variable steps the last point at or before each
    multiple of RECORD_INTERVAL (each point once)."""
    if np.ndim(step_size) == 0:
        return np.arange(0, len(times), max(1, round(RECORD_INTERVAL / step_size)))
    instants = np.arange(math.floor(times[-1] / RECORD_INTERVAL + 1e-9) + 1) * RECORD_INTERVAL
    return np.unique(np.searchsorted(times, instants + 1e-9, side="right") - 1)


def point_at(times: np.ndarray, step_size: float | np.ndarray, t: float) -> int:
    """The index of the first communication point at or after t [s] (to 1 ns): with a fixed
    step, the nearest multiple of it."""
    if np.ndim(step_size) == 0:
        return round(t / step_size)
    return int(np.searchsorted(times, t - 1e-9))


def event_lag(times: np.ndarray, phases: list[tuple[str, float, float]]) -> float:
    """The largest delay [s] between a phase's start (where the scenario's inputs switch:
    locks, payload) and the first communication point at or after it, where the mechanism
    first sees the switch; 0 when every phase starts on a communication point (to 1 ns)."""
    lags = [times[min(point_at(times, times, t0), len(times) - 1)] - t0
            for _, t0, _ in phases[1:]]
    return max((round(lag * 1e9) * 1e-9 for lag in lags), default=0.0)


def _add_drive_columns(frame: pd.DataFrame, trace: DriveTrace,
                       cumulative: dict[str, np.ndarray], suffix: str, rows: np.ndarray) -> None:
    """One drive's columns at the recorded communication points rows: `<position>_ref`, then
    V, i, the effort (named after the FMU input), P_elec, E_in and E_drawn, and the power
    bond's W_bond_drive, W_bond_joint, W_bond_error with the joint's suffix; cumulative: those
    energies up to every communication point [J].

    The drive columns at time t_j hold the values of the step that starts at t_j (the last
    row holds those of the final step); cumulative energies are summed up to t_j.
    """
    voltage, current = trace.voltage, trace.current
    index = np.minimum(rows, len(voltage) - 1)
    frame[f"{trace.joint.position}_ref"] = trace.reference[rows]
    frame[f"V{suffix}"] = voltage[index]
    frame[f"i{suffix}"] = current[index]
    frame[trace.joint.effort] = trace.effort[index]
    frame[f"P_elec{suffix}"] = (voltage * current)[index]
    for name in ("E_in", "E_drawn", *metrics.BOND):
        frame[f"{name}{suffix}"] = cumulative[name][rows]


def _add_total_columns(frame: pd.DataFrame, suffixes: list[str]) -> None:
    """P_elec, E_in and E_drawn summed over the drives."""
    for name in ("P_elec", "E_in", "E_drawn"):
        frame[name] = sum(frame[f"{name}{s}"] for s in suffixes)
