"""Drive metrics (defined in docs/results.md), from a drive's record of a run (`DriveTrace`).

The drive's signals are held over each communication step k of length dt: voltage V[k],
step-average current i[k] and effort tau[k] (fmu_src.units.drive.dc_motor.SampledMotor); the
joint travels dq[k] over the step. Each step's energies are
`fmu_src.units.drive.dc_motor.step_energies`, the one definition the FMU, the CSV columns and
the monolithic reference share; here they are summed.

Effort metrics are named for what they are: a revolute joint's torque `tau_peak`, `tau_rms`
[N m], a prismatic joint's force `F_peak`, `F_rms` [N]. A run with several joints (one drive
each) reports each drive's metrics with the joint's name as suffix (`tau_peak_q1`,
`F_peak_q2`, `E_drawn_q2`) and the energies of TOTALS summed over the drives under the plain
names: each drive has its own supply, so E_drawn is the sum of what each draws.
"""

from __future__ import annotations

import numpy as np

from fmu_src.units.drive.dc_motor import DriveEnergies, inductor_energy
from harness.drive.motor import JointDrive
from harness.drive.trace import DriveTrace

# by joint kind: the names of the effort's peak and RMS, and of the joint's peak speed
EFFORT_METRICS = {"revolute": ("tau_peak", "tau_rms"), "prismatic": ("F_peak", "F_rms")}
SPEED_METRICS = {"revolute": "omega_peak", "prismatic": "v_peak"}
ENERGIES = DriveEnergies._fields
# what the summary reports of a joint's drive (`drive_report`): its parts, gear ratio, the
# motor's nominal current [A] and rated power [W], and whether its RMS current is within it
DRIVE = ("drive", "gear_ratio", "I_nom", "P_nom", "drive_ok")
METRICS = (*ENERGIES, "E_inductor", *(name for names in EFFORT_METRICS.values() for name in names),
           "i_rms", "I_rms", "I_peak", *SPEED_METRICS.values(), "V_peak", "track_err_max",
           "track_err_rms", *DRIVE, "eps")
TOTALS = (*ENERGIES, "E_inductor")
# the power bond between drive and joint (docs/results.md#power-bonds): the energy that left
# the drive, the energy that reached the joint and their difference, the coupling's error
BOND = ("W_bond_drive", "W_bond_joint", "W_bond_error")


def drive_metrics(trace: DriveTrace) -> dict[str, float]:
    """Energies [J], effort [N m or N], current [A], voltage [V] and tracking errors [rad or m].

    E_in: net electrical energy (regeneration credited); E_drawn: energy from a supply that
    cannot take energy back; E_copper: armature losses; E_mech: integral of |tau omega|;
    W_link: net mechanical work on the joint; E_inductor: magnetic energy left at the end,
    so that E_in = E_copper + E_gear + the work the drive passes on + E_inductor;
    I_peak: the largest step-average current [A]; omega_peak (v_peak): the joint's largest
    speed [rad/s or m/s].
    """
    n = len(trace.voltage)
    effort, current = trace.effort, trace.current
    error = trace.reference[:n] - trace.position[:n]
    peak, rms = EFFORT_METRICS[trace.joint.kind]
    # RMS over time: with variable steps each step weighs its length
    weights = None if np.ndim(trace.step_size) == 0 else trace.step_size
    energies = trace.energies()
    return {
        **{name: float(np.sum(energy)) for name, energy in energies._asdict().items()},
        "E_inductor": float(inductor_energy(trace.motor, trace.final_current)),
        peak: float(np.max(np.abs(effort))),
        rms: float(np.sqrt(np.average(effort ** 2, weights=weights))),
        "i_rms": float(np.sqrt(np.average(current ** 2, weights=weights))),
        "I_peak": float(np.max(np.abs(current))),
        SPEED_METRICS[trace.joint.kind]: float(np.max(np.abs(trace.speed))),
        "V_peak": float(np.max(np.abs(trace.voltage))),
        "track_err_max": float(np.max(np.abs(error))),
        "track_err_rms": float(np.sqrt(np.average(error ** 2, weights=weights))),
        **{name: float(np.sum(energy)) for name, energy
           in zip(BOND, bond_energies(trace, energies), strict=True)},
    }


def drive_report(drive: JointDrive, metrics: dict[str, float]) -> dict[str, object]:
    """A joint's drive metrics with what the summary reports of its drive (DRIVE): I_rms
    (the contract's i_rms, beside I_nom for the comparison), and drive_ok, false when the RMS
    current exceeds the motor's nominal current: a failed design."""
    return {**metrics, "I_rms": metrics["i_rms"], "drive": drive.label,
            "gear_ratio": drive.gear_ratio, "I_nom": drive.I_nom, "P_nom": drive.P_nom,
            "drive_ok": metrics["i_rms"] <= drive.I_nom}


def bond_energies(trace: DriveTrace, energies: DriveEnergies | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step [J] (docs/results.md#power-bonds): the energy that left the drive through its
    shaft, the effort it applied times the speed it held (tau_drive omega_held h, exact over
    the step, as its torque is linear in its current); the energy the joint received, the
    effort it held times its own travel (tau_held dq, exact: the mechanism integrates its
    speed and its W_drive with the same sub-steps); and their difference, the coupling's."""
    n = len(trace.voltage)
    out = trace.shaft_effort * trace.speed[:n] * trace.steps
    received = (trace.energies() if energies is None else energies).W_link
    return out, received, received - out


def run_metrics(per_joint: dict[str, dict[str, float]]) -> dict[str, float]:
    """A run's metrics from each drive's metrics (`drive_metrics`, or some of them) by joint
    name: one joint's as they are; for several joints the TOTALS among them, then every
    drive's metrics suffixed with its joint's name."""
    first = next(iter(per_joint.values()))
    if len(per_joint) == 1:
        return dict(first)
    totals = {name: sum(m[name] for m in per_joint.values()) for name in TOTALS
              if name in first}
    if "drive_ok" in first:  # the run's design fails with any of its drives
        totals["drive_ok"] = all(m["drive_ok"] for m in per_joint.values())
    return totals | {f"{name}_{joint}": value for joint, m in per_joint.items()
                     for name, value in m.items()}


def efficaciousness(drawn: float, baseline_drawn: float) -> float:
    """Ciupitu eq. 31 on the drawn energy: eps = 1 - E_balanced / E_unbalanced."""
    return 1.0 - drawn / baseline_drawn
