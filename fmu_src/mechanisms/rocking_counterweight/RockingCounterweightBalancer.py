"""FMI 2.0 Co-Simulation slave of Ciupitu's rocking counterweight
(README.md).

A thin layer over `fmu_src.mechanisms.rocking_counterweight.physics`: it maps FMI variables to
the physics, applies the payload events at communication points and integrates the physics over
each communication step. """

from __future__ import annotations

from typing import Any

from fmu_src.mechanisms.payload_arm import PayloadArmSlave, payload_arm
from fmu_src.mechanisms.rocking_counterweight import physics


class RockingCounterweightBalancer(PayloadArmSlave):
    """1-DOF arm balanced by a counterweight on a bar pivoted on the arm and tied to the
    ground by a second bar (Ciupitu 2018, Figure 4b), plus a fixed counterweight."""

    physics = physics

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Passive rocking counterweight balancer (Ciupitu 2018, Figure 4b): "
                            "1-DOF arm, counterweight on a bar pivoted on the arm, tied to a "
                            "ground pivot by a second bar")


REGISTRATION = payload_arm(
    physics, ("theta", "omega", "tau_gravity", "E_p", "E_kin", "M_b", "M_u", "X_cw", "Y_cw", "psi"),
    "Y_cw")
