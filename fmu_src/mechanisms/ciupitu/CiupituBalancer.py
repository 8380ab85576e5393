"""FMI 2.0 Co-Simulation slave of Ciupitu's passive translational counterweight
(README.md).

A thin layer over `fmu_src.mechanisms.ciupitu.physics`: it maps FMI variables to the physics and
integrates it over each communication step. """

from __future__ import annotations

from typing import Any

from fmu_src.mechanisms.ciupitu import physics
from fmu_src.mechanisms.payload_arm import ARM_OUTPUTS, PayloadArmSlave, payload_arm

OUTPUTS = (
    ARM_OUTPUTS["theta"],
    ARM_OUTPUTS["omega"],
    ("OB", "m", "Distance from O to the sliding counterweight B (eq. 13)"),
    ("tau_gravity", "N.m", "Gravity torque on the arm about O along theta, -dE_p/dtheta "
                           "= -(M_u + M_bar) when the fixed counterweight balances m c"),
    ARM_OUTPUTS["E_p"],
    ARM_OUTPUTS["E_kin"],
    ARM_OUTPUTS["M_g"],
    ("M_b", "N.m", "Moment of the counterweight's weight about O, m2 g OB cos(phi) (eq. 12)"),
    ARM_OUTPUTS["M_u"],
    ("M_bar", "N.m", "Static moment about O of the bar AB's force on the counterweight, "
                     "m2 g (dOB/dphi) sin(phi) (omitted by the paper)"),
    ARM_OUTPUTS["W_drive"],
    ARM_OUTPUTS["E_loss"],
    ARM_OUTPUTS["E_added"],
)


class CiupituBalancer(PayloadArmSlave):
    """1-DOF arm balanced by a counterweight sliding along it, guided by a bar to a ground
    pivot above the arm's pivot (Ciupitu 2018, Figure 4a), plus a fixed counterweight."""

    physics = physics
    output_table = OUTPUTS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Passive translational counterweight balancer (Ciupitu 2018, "
                            "Figure 4a): 1-DOF arm, counterweight sliding along the arm, "
                            "guided by one bar to a ground pivot")


REGISTRATION = payload_arm(
    physics, ("theta", "omega", "OB", "tau_gravity", "E_p", "E_kin", "M_g", "M_b", "M_u", "M_bar"),
    initial_parameters={"omega0": 0.5})
