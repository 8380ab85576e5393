"""FMI 2.0 Co-Simulation slave of Ciupitu's passive translational counterweight
(README.md).

A thin layer over `fmu_src.mechanisms.ciupitu.physics`: it maps FMI variables to the physics and
integrates it over each communication step. """

from __future__ import annotations

from typing import Any

from fmu_src.mechanisms.ciupitu import physics
from fmu_src.mechanisms.payload_arm import PayloadArmSlave, payload_arm


class CiupituBalancer(PayloadArmSlave):
    """1-DOF arm balanced by a counterweight sliding along it, guided by a bar to a ground
    pivot above the arm's pivot (Ciupitu 2018, Figure 4a), plus a fixed counterweight."""

    physics = physics

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Passive translational counterweight balancer (Ciupitu 2018, "
                            "Figure 4a): 1-DOF arm, counterweight sliding along the arm, "
                            "guided by one bar to a ground pivot")


REGISTRATION = payload_arm(
    physics, ("theta", "omega", "OB", "tau_gravity", "E_p", "E_kin", "M_g", "M_b", "M_u", "M_bar"),
    "OB", initial_parameters={"omega0": 0.5})
