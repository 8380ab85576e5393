"""Drive metrics (defined in docs/results.md), from per-step records of a run.

The drive's signals are held over each communication step k of length dt: voltage V[k],
step-average current i[k] and torque tau[k] (fmu_src.dc_motor.SampledMotor); the link turns by
dtheta[k] over the step. So V i dt is the step's exact electrical energy and tau dtheta its
exact mechanical work on the link. For a prismatic joint read force [N] for torque, metres for
radians.

A run with several joints (one drive each) reports each drive's metrics with the joint's name
as suffix (`tau_peak_q1`, `E_drawn_q2`) and the energies of TOTALS summed over the drives under
the plain names: each drive has its own supply, so E_drawn is the sum of what each draws.
"""

from __future__ import annotations

import numpy as np

METRICS = ("E_in", "E_drawn", "E_copper", "E_mech", "W_link", "E_inductor", "tau_peak",
           "tau_rms", "i_rms", "V_peak", "track_err_max", "track_err_rms", "eps")
TOTALS = ("E_in", "E_drawn", "E_copper", "E_mech", "W_link", "E_inductor")


def drive_metrics(dt: float, voltage: np.ndarray, current: np.ndarray, torque: np.ndarray,
                  dtheta: np.ndarray, error: np.ndarray, R_a: float, L_a: float,
                  final_current: float) -> dict[str, float]:
    """Energies [J], torques [N m], currents [A], voltage [V] and tracking errors [rad].

    E_in: net electrical energy (regeneration credited); E_drawn: energy from a supply that
    cannot take energy back; E_copper: armature losses; E_mech: integral of |tau omega|;
    W_link: net mechanical work on the link; E_inductor: magnetic energy left at the end,
    so that E_in = E_copper + W_link / eta ... (eta = 1 by default) + E_inductor.
    """
    power = voltage * current
    return {
        "E_in": float(np.sum(power) * dt),
        "E_drawn": float(np.sum(np.maximum(power, 0.0)) * dt),
        "E_copper": float(R_a * np.sum(current ** 2) * dt),
        "E_mech": float(np.sum(np.abs(torque * dtheta))),
        "W_link": float(np.sum(torque * dtheta)),
        "E_inductor": 0.5 * L_a * final_current ** 2,
        "tau_peak": float(np.max(np.abs(torque))),
        "tau_rms": float(np.sqrt(np.mean(torque ** 2))),
        "i_rms": float(np.sqrt(np.mean(current ** 2))),
        "V_peak": float(np.max(np.abs(voltage))),
        "track_err_max": float(np.max(np.abs(error))),
        "track_err_rms": float(np.sqrt(np.mean(error ** 2))),
    }


def run_metrics(per_joint: dict[str, dict[str, float]]) -> dict[str, float]:
    """A run's metrics from each drive's metrics (`drive_metrics`, or some of them) by joint
    name: one joint's as they are; for several joints the TOTALS among them, then every
    drive's metrics suffixed with its joint's name."""
    first = next(iter(per_joint.values()))
    if len(per_joint) == 1:
        return dict(first)
    totals = {name: sum(m[name] for m in per_joint.values()) for name in TOTALS
              if name in first}
    return totals | {f"{name}_{joint}": value for joint, m in per_joint.items()
                     for name, value in m.items()}


def efficaciousness(drawn: float, baseline_drawn: float) -> float:
    """Ciupitu eq. 31 on the drawn energy: eps = 1 - E_balanced / E_unbalanced."""
    return 1.0 - drawn / baseline_drawn
