"""FMI 2.0 Co-Simulation slave of the Demian-Klimchik prismatic compensator (README.md).

A thin layer over `fmu_src.mechanisms.prismatic.physics`: it maps FMI variables to the physics
and integrates it over each communication step. """

from __future__ import annotations

from typing import Any

from pythonfmu.default_experiment import DefaultExperiment

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.mechanism import ANGULAR, LINEAR, Port, Registration, Run, rest_to_rest_move
from fmu_src.mechanisms.prismatic import physics


class PrismaticCompensator(MechanismSlave):
    """2-DoF RP arm with the spring gravity compensator of Demian and Klimchik (2022)."""

    physics = physics
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=8.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Gravity compensator for a 2-DoF RP arm (Demian and Klimchik "
                            "2022): pin-slot spring with constant-tension wire on the prismatic "
                            "joint, two springs on the revolute joint, self-locking worms")
        for name, unit, description in CALCULATED_PARAMETERS:
            self.add_calculated_parameter(name, unit, description)
        self.add_input("tau1", 0.0, "N.m", "Drive torque on the revolute joint")
        self.add_input("f2", 0.0, "N", "Drive force on the prismatic joint, outward positive")
        for name, unit, description in OUTPUTS:
            self.add_output(name, unit, description)

    def initialise(self, params: physics.Parameters) -> None:
        for name, _, _ in CALCULATED_PARAMETERS:
            setattr(self, name, getattr(params, name))
        super().initialise(params)


CALCULATED_PARAMETERS = (
    ("J1", "kg.m2", "Inertia of link 1 about O, I1 + m1 lc1^2"),
    ("k1_used", "N/m", "Pin-slot spring stiffness in use: m2 g / (2 r) (eq. 3.6) with "
     "design_springs, else k1"),
    ("k2_used", "N/m", "Stiffness of spring CD in use: lc1 m1 g / (c d) (eq. 3.13) with "
     "design_springs, else k2"),
    ("k3_used", "N/m", "Stiffness of spring AB in use: m2 g ls0 / (a b) (eq. 3.15) with "
     "design_springs, else k3"),
    ("rho_used", "1", "Belt ratio q*/q2 in use: b / ls0 (eq. 3.17) with design_springs, else rho"),
)

OUTPUTS = (
    ("q1", "rad", "Angle of link 1 from the horizontal, counter-clockwise positive"),
    ("q1_dot", "rad/s", "Revolute joint speed"),
    ("q2", "m", "Prismatic joint travel along the link (m2 at ls0 + q2 from O)"),
    ("q2_dot", "m/s", "Prismatic joint speed"),
    ("tau1_gravity", "N.m", "Gravity torque effort of the revolute joint, uncompensated "
     "(eq. 3.1)"),
    ("f2_gravity", "N", "Gravity force effort of the prismatic joint, uncompensated (eq. 3.3)"),
    ("tau1_gravity_residual", "N.m", "Torque a drive must supply to hold the arm at rest: "
     "gravity effort minus spring compensation"),
    ("f2_gravity_residual", "N", "Force a drive must supply to hold the arm at rest: gravity "
     "effort minus spring and wire compensation"),
    ("T_wire", "N", "Tension of the pin-slot spring wire, k1 r sin(q1) (0 when slack); 2 T_wire "
     "acts on the slider"),
    ("f2_worm", "N", "Force of the self-locking worms on the prismatic joint beyond the spring "
     "energies (2 T_wire, plus dE_k3/dq2 when self_locking)"),
    ("E_grav", "J", "Gravitational potential energy of m1 and m2 (0 at q1 = 0)"),
    ("E_springs", "J", "Elastic energy of springs k1, k2, k3"),
    ("E_kin", "J", "Kinetic energy of the arm and of the drive rotors (J_drive1, m_drive2)"),
    ("W_drive", "J", "Cumulative work of tau1 and f2 on the arm"),
    ("W_worm", "J", "Cumulative work of the worms on the arm (integral of f2_worm q2_dot)"),
    ("E_friction", "J", "Cumulative energy dissipated by d1 and d2"),
    ("E_loss", "J", "Cumulative energy dissipated: E_friction plus the end-stop impacts of q2"),
    ("E_added", "J", "Energy brought in by masses joining or leaving: always 0 here (the "
                     "mechanisms' common ledger E_grav + E_springs + E_kin + E_loss - W_drive - "
                     "W_worm - E_added is constant)"),
)


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
        ("gravity residuals: efforts to hold the arm", "N m | N",
         ("tau1_gravity_residual", "f2_gravity_residual")),
        ("energies", "J", ("E_grav", "E_springs", "E_kin", "W_worm")),
    ),
)
