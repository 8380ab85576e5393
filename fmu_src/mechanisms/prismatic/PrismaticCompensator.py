"""FMI 2.0 Co-Simulation slave of the Demian-Klimchik prismatic compensator (README.md).

A thin layer over `fmu_src.mechanisms.prismatic.physics`: it maps FMI variables to the physics
and integrates it over each communication step. """

from __future__ import annotations

from typing import Any

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.fmi.vocabulary import DefaultExperiment
from fmu_src.mechanism import ANGULAR, LINEAR, Port, Registration, Run, rest_to_rest_move
from fmu_src.mechanisms.prismatic import physics


class PrismaticCompensator(MechanismSlave):
    """2-DoF RP arm with the spring gravity compensator of Demian and Klimchik (2022)."""

    physics = physics
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=8.0, step_size=1e-3)
    calculated_parameters = (
        ("J1", "kg.m2", "Inertia of link 1 about O, I1 + m1 lc1^2"),
        ("k1_used", "N/m", "Pin-slot spring stiffness in use: m2 g / (2 r) (eq. 3.6) with "
         "design_springs, else k1"),
        ("k2_used", "N/m", "Stiffness of spring CD in use: lc1 m1 g / (c d) (eq. 3.13) with "
         "design_springs, else k2"),
        ("k3_used", "N/m", "Stiffness of spring AB in use: m2 g ls0 / (a b) (eq. 3.15) with "
         "design_springs, else k3"),
        ("rho_used", "1", "Belt ratio q*/q2 in use: b / ls0 (eq. 3.17) with design_springs, "
         "else rho"),
    )

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Gravity compensator for a 2-DoF RP arm (Demian and Klimchik "
                            "2022): pin-slot spring with constant-tension wire on the prismatic "
                            "joint, two springs on the revolute joint, self-locking worms")


REGISTRATION = Registration(
    physics=physics,
    ports=(Port(ANGULAR, "q1", "tau1", "q1_dot", "q1"), Port(LINEAR, "q2", "f2", "q2_dot", "q2")),
    ledger={"E_grav": 1, "E_springs": 1, "E_kin": 1, "E_loss": 1, "W_drive": -1, "W_worm": -1,
            "E_added": -1},
    reference_run=rest_to_rest_move(
        {"tau1": (0.1, "N m"), "f2": (0.02, "N")}, {},
        ("q1", "q1_dot", "q2", "q2_dot", "tau1_gravity_residual", "f2_gravity_residual",
         "T_wire", "f2_worm", "W_drive", "W_worm")),
    moving_run=Run({}, {"tau1": 0.5, "f2": 1.0}, 2.0),
    dependency_probes=(Run({}, {"tau1": 1.0, "f2": 1.0}, 0.3),),
    plot_panels=(
        ("gravity residual on q1: torque to hold the arm", "N m", ("tau1_gravity_residual",)),
        ("gravity residual on q2: force to hold the arm", "N", ("f2_gravity_residual",)),
        ("energies", "J", ("E_grav", "E_springs", "E_kin", "W_worm")),
    ),
)
