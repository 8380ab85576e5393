"""FMI 2.0 Co-Simulation slave of Ciupitu's rocking counterweight
(docs/rocking_counterweight.md).

A thin layer over `fmu_src.rocking_counterweight`: it maps FMI variables to the physics,
applies the payload events at communication points and integrates the physics over each
communication step.
"""

from __future__ import annotations

from typing import Any

from pythonfmu.default_experiment import DefaultExperiment

from fmu_src import rocking_counterweight as physics
from fmu_src.fmi_base import PayloadArmSlave
from fmu_src.mechanism import payload_arm

OUTPUTS = (
    ("theta", "rad", "Arm angle from the upward vertical, counter-clockwise positive "
                     "(the paper's phi = pi/2 - theta)"),
    ("omega", "rad/s", "Arm angular velocity"),
    ("tau_gravity", "N.m", "Gravity torque on the arm about O along theta, -dE_p/dtheta "
                           "= -M_u when the fixed counterweight balances m c"),
    ("E_p", "J", "Gravitational potential energy of link, payload and both counterweights"),
    ("E_kin", "J", "Kinetic energy of link, payload, counterweights and drive rotor"),
    ("M_g", "N.m", "Payload moment about O, -payload g w cos(phi) (eq. 8, paper's sign)"),
    ("M_b", "N.m", "Moment of the rocking counterweight and its bars about O, -m2 g dY_cw/dphi "
                   "(paper's sign)"),
    ("M_u", "N.m", "Unbalanced moment M_b + M_g (eq. 16)"),
    ("X_cw", "m", "Counterweight position, horizontal towards the payload's side (the paper's "
                  "X = -x)"),
    ("Y_cw", "m", "Counterweight height above O"),
    ("psi", "rad", "Angle of the counterweight bar (A -> B) from the arm, counter-clockwise in "
                   "the paper's frame"),
    ("W_drive", "J", "Cumulative work of tau_drive on the arm"),
    ("E_loss", "J", "Cumulative energy dissipated: pivot friction, payload picked up while "
                    "moving"),
    ("E_added", "J", "Cumulative energy brought in (+) or taken out (-) by payload joining or "
                     "leaving; E_p + E_kin + E_loss - W_drive - E_added is constant"),
)
# The inputs each output depends on directly (`physics.outputs`), its ModelStructure
# dependencies; an output not listed is a function of the state alone.
INPUT_DEPENDENCIES = {name: ("payload",) for name in ("tau_gravity", "E_p", "E_kin", "M_g", "M_u")}


class RockingCounterweightBalancer(PayloadArmSlave):
    """1-DOF arm balanced by a counterweight on a bar pivoted on the arm and tied to the
    ground by a second bar (Ciupitu 2018, Figure 4b), plus a fixed counterweight."""

    physics = physics
    parameters_type = physics.Parameters
    output_table = OUTPUTS
    input_dependencies = INPUT_DEPENDENCIES
    # as CiupituBalancer: the harness's 1 ms step, 20 s for several strokes of a cycle
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Passive rocking counterweight balancer (Ciupitu 2018, Figure 4b): "
                            "1-DOF arm, counterweight on a bar pivoted on the arm, tied to a "
                            "ground pivot by a second bar")


REGISTRATION = payload_arm(
    physics, ("theta", "omega", "tau_gravity", "E_p", "E_kin", "M_b", "M_u", "X_cw", "Y_cw", "psi"))
