"""FMI 2.0 Co-Simulation slave of Ciupitu's passive translational counterweight
(docs/mechanisms.md).

A thin layer over `fmu_src.ciupitu`: it maps FMI variables to the physics and integrates it
over each communication step.
"""

from __future__ import annotations

from typing import Any

from pythonfmu.default_experiment import DefaultExperiment

from fmu_src import ciupitu as physics
from fmu_src.fmi_base import PayloadArmSlave
from fmu_src.mechanism import payload_arm

OUTPUTS = (
    ("theta", "rad", "Arm angle from the upward vertical, counter-clockwise positive "
                     "(the paper's phi = pi/2 - theta)"),
    ("omega", "rad/s", "Arm angular velocity"),
    ("OB", "m", "Distance from O to the sliding counterweight B (eq. 13)"),
    ("tau_gravity", "N.m", "Gravity torque on the arm about O along theta, -dE_p/dtheta "
                           "= -(M_u + M_bar) when the fixed counterweight balances m c"),
    ("E_p", "J", "Gravitational potential energy of link, payload and both counterweights"),
    ("E_kin", "J", "Kinetic energy of link, payload, counterweights and drive rotor"),
    ("M_g", "N.m", "Payload moment about O, -payload g w cos(phi) (eq. 8, paper's sign)"),
    ("M_b", "N.m", "Moment of the counterweight's weight about O, m2 g OB cos(phi) (eq. 12)"),
    ("M_u", "N.m", "Unbalanced moment M_b + M_g (eq. 16)"),
    ("M_bar", "N.m", "Static moment about O of the bar AB's force on the counterweight, "
                     "m2 g (dOB/dphi) sin(phi) (omitted by the paper)"),
    ("W_drive", "J", "Cumulative work of tau_drive on the arm"),
    ("E_loss", "J", "Cumulative energy dissipated: pivot friction, payload picked up while "
                    "moving"),
    ("E_added", "J", "Cumulative energy brought in (+) or taken out (-) by payload joining or "
                     "leaving; E_p + E_kin + E_loss - W_drive - E_added is constant"),
)
# The inputs each output depends on directly (`physics.outputs`), its ModelStructure
# dependencies; an output not listed is a function of the state alone.
INPUT_DEPENDENCIES = {name: ("payload",)
                      for name in ("tau_gravity", "E_p", "E_kin", "M_g", "M_u")}


class CiupituBalancer(PayloadArmSlave):
    """1-DOF arm balanced by a counterweight sliding along it, guided by a bar to a ground
    pivot above the arm's pivot (Ciupitu 2018, Figure 4a), plus a fixed counterweight."""

    physics = physics
    parameters_type = physics.Parameters
    output_table = OUTPUTS
    input_dependencies = INPUT_DEPENDENCIES
    # 1 ms is the harness's communication step (as for SelfRegulatingBalancer); 20 s spans
    # several strokes of a rocking cycle and many periods of the default arm's free swing.
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Passive translational counterweight balancer (Ciupitu 2018, "
                            "Figure 4a): 1-DOF arm, counterweight sliding along the arm, "
                            "guided by one bar to a ground pivot")


REGISTRATION = payload_arm(
    physics, ("theta", "omega", "OB", "tau_gravity", "E_p", "E_kin", "M_g", "M_b", "M_u", "M_bar"),
    initial_parameters={"omega0": 0.5})
