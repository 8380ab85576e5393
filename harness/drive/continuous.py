"""The drives of a run as a continuous system, for an engine that integrates them with the
mechanism in one solver (the monolithic reference, Model Exchange): per joint the motor's
armature equation and the continuous PID (filtered derivative) that each discrete controller
approximates, with the drive's energies integrated as extra states, their rates those of
`fmu_src.units.drive.dc_motor.drive_powers`, the definition the sampled drive's metrics share.

`ContinuousDrives` owns a slice of the solver's state vector: first DRIVE_STATES per joint
(armature current [A], PID integral [V], filtered error [rad or m]), then the ENERGIES per
joint [J]. The engine gives it each joint's position, speed and reference; it gives each
joint's effort and the slice's rates. A drive switched off for a phase
(`DrivePlan.phase_enabled`) carries no current and its controller holds; switched on, its
controller starts with the integral reset and no derivative kick.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fmu_src.units.drive.dc_motor import armature_rate, drive_powers, transmitted_effort
from harness.drive.metrics import BOND, ENERGIES
from harness.drive.plan import DrivePlan
from harness.drive.trace import DriveTrace

DRIVE_STATES = 3  # per joint: armature current, PID integral, filtered error


class ContinuousDrives:
    """The drives of plans (one per joint, in the scenario's order) as the state slice that
    starts at index `first` of a solver's state vector."""

    def __init__(self, plans: Sequence[DrivePlan], first: int) -> None:
        self.plans = tuple(plans)
        self.first = first
        self.energy_first = first + DRIVE_STATES * len(self.plans)
        self.size = (DRIVE_STATES + len(ENERGIES)) * len(self.plans)

    def _states(self, y: np.ndarray, j: int) -> np.ndarray:
        start = self.first + DRIVE_STATES * j
        return y[start:start + DRIVE_STATES]

    def initial(self) -> list[float]:
        """The slice at t = 0: each drive in its planned equilibrium start, no energy yet."""
        states = [value for plan in self.plans for value in (
            plan.hold_current, plan.integral0, plan.reference[0] - plan.position0)]
        return states + [0.0] * (len(ENERGIES) * len(self.plans))

    def signals(self, y: np.ndarray, j: int, error: float, speed: float, on: bool
                ) -> tuple[float, float, float]:
        """Joint j's drive at the state y, its tracking error (reference less position) and
        the joint's speed: (voltage [V], current [A], effort [N m or N]); a drive that is
        off gives 0 V, 0 A and no effort."""
        if not on:
            return 0.0, 0.0, 0.0
        plan, g = self.plans[j], self.plans[j].gains
        current, integral, filtered = self._states(y, j)
        voltage = g.Kp * error + integral + g.Kd / g.T_f * (error - filtered)
        limit = plan.motor.V_supply
        voltage = min(max(voltage, -limit), limit)
        return voltage, current, transmitted_effort(plan.motor, current, speed)

    def rates(self, y: np.ndarray, positions: Sequence[float], speeds: Sequence[float],
              references: Sequence[float], phase: int) -> tuple[list[float], list[float]]:
        """Each joint's effort [N m or N] at the state y in the phase, and the rates of the
        slice (its drive states', then its energies' [W])."""
        efforts, drive_rates, energy_rates = [], [], []
        for j, plan in enumerate(self.plans):
            on = plan.phase_enabled[phase]
            error, speed = references[j] - positions[j], speeds[j]
            voltage, current, effort = self.signals(y, j, error, speed, on)
            filtered = self._states(y, j)[2]
            efforts.append(effort)
            drive_rates += [armature_rate(plan.motor, voltage, current, speed) if on else 0.0,
                            plan.gains.Ki * error if on else 0.0,
                            (error - filtered) / plan.gains.T_f]
            energy_rates += drive_powers(plan.motor, voltage, current, effort, speed)
        return efforts, drive_rates + energy_rates

    def switched(self, y: np.ndarray, phase: int, references: Sequence[float],
                 positions: Sequence[float]) -> np.ndarray:
        """The state at the start of a phase with the drives switched as it says: a drive
        switched off drops its current (the armature's magnetic energy goes to E_copper); one
        switched on starts its controller with the integral reset and the filtered error at
        the error (no derivative kick)."""
        y = y.copy()
        for j, plan in enumerate(self.plans):
            on = plan.phase_enabled
            if phase == 0 or on[phase] == on[phase - 1]:
                continue
            state = self.first + DRIVE_STATES * j
            if on[phase]:
                y[state + 1] = 0.0
                y[state + 2] = references[j] - positions[j]
            else:
                copper = self.energy_first + len(ENERGIES) * j + ENERGIES.index("E_copper")
                y[copper] += 0.5 * plan.motor.L_a * y[state] ** 2
                y[state] = 0.0
        return y

    def traces(self, samples: np.ndarray, positions: Sequence[np.ndarray],
               speeds: Sequence[np.ndarray]) -> list[DriveTrace]:
        """Each joint's drive at the communication points from the solver's states there
        (samples, one row per point) and the joint's positions and speeds: the voltage,
        current and effort at each step's start, held over the step, for the series and the
        effort, current and tracking metrics (the energies are the solver's,
        `cumulative_energies`)."""
        traces = []
        for j, plan in enumerate(self.plans):
            on = np.append(plan.enabled, plan.enabled[-1])
            signals = np.array([self.signals(y, j, r - q, w, o) for y, r, q, w, o in zip(
                samples, plan.reference, positions[j], speeds[j], on, strict=True)])
            voltage, current, effort = signals.T
            traces.append(DriveTrace(plan.joint, plan.motor, plan.step_size, voltage[:-1],
                                     current[:-1], effort[:-1], current, positions[j],
                                     speeds[j], plan.reference, plan.enabled))
        return traces

    def cumulative_energies(self, samples: np.ndarray) -> list[dict[str, np.ndarray]]:
        """Per joint, the drive's energies the solver integrated up to every communication
        point [J] (ENERGIES, and the power bond's, which has no coupling error)."""
        out = []
        for j in range(len(self.plans)):
            first = self.energy_first + len(ENERGIES) * j
            cumulative = dict(zip(ENERGIES, samples[:, first:first + len(ENERGIES)].T,
                                  strict=True))
            out.append(cumulative | dict(zip(BOND, (cumulative["W_link"], cumulative["W_link"],
                                                    np.zeros(len(samples))), strict=True)))
        return out

