"""FMI 2.0 Co-Simulation slave of the spring balancer with an actively relocated frame joint
(Ciupitu 2018, Fig. 8).

A thin layer over `fmu_src.mechanisms.active_spring.physics` (the common plumbing is
`MechanismSlave`'s); it warns through the FMU log when the spring is compressed (the model's
linear force law pushes there, which an extension spring cannot). """

from __future__ import annotations

from typing import Any

from pythonfmu.default_experiment import DefaultExperiment

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.mechanism import ANGULAR, LINEAR, Port, Registration, Run, rest_to_rest_move
from fmu_src.mechanisms.active_spring import physics


class ActiveSpringBalancer(MechanismSlave):
    """1-DOF link balanced by a spring whose frame joint a prismatic joint, driven through a
    screw with thread friction, moves along the vertical (Ciupitu 2018, Section 3)."""

    physics = physics
    hidden_state = ("state", "previous_inputs", "compression_reported")
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=5.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Spring gravity balancer with active relocation of the spring's "
                            "frame joint by one prismatic joint on a screw with thread "
                            "friction, self-locking by default (Ciupitu 2018, Fig. 8)")
        self.add_input("tau_drive", 0.0, "N.m", "Drive torque on the link about O")
        self.add_input("F_adjust", 0.0, "N", "Actuator's force on the screw along +q (upward): "
                       "its torque times 2 pi / lead")
        self.add_input("payload", 0.0, "kg", "Payload mass at distance w", min=0.0)
        for name, unit, description in OUTPUTS:
            self.add_output(name, unit, description, INPUT_DEPENDENCIES.get(name, ()))
        self.compression_reported = False   # once per spell of F_s < 0

    def initialise(self, params: physics.Parameters) -> None:
        self.compression_reported = False
        super().initialise(params)

    def step(self, dt: float) -> None:
        super().step(dt)
        spring = self.output_values
        if spring.F_s < 0.0 and not self.compression_reported:
            self.warn(f"spring in compression (F_s = {spring.F_s:.4g} N at l_s = "
                      f"{spring.l_s:.4g} m, free length {self.params.free_length:.4g} m): the "
                      "model's linear law pushes, an extension spring would go slack")
        self.compression_reported = spring.F_s < 0.0

    def restore_hidden_state(self, hidden: dict[str, Any]) -> None:
        super().restore_hidden_state(hidden)
        self.compression_reported = bool(hidden["compression_reported"])


OUTPUTS = (
    ("theta", "rad", "Link angle from the upward vertical, counter-clockwise positive"),
    ("omega", "rad/s", "Link angular velocity"),
    ("q", "m", "Travel of the prismatic joint along +y"),
    ("q_dot", "m/s", "Speed of the prismatic joint"),
    ("Y_B", "m", "Ordinate of the spring's frame joint B, Y_B0 + q"),
    ("l_s", "m", "Spring length A-B (eq. 21)"),
    ("F_s", "N", "Spring force F_s0 + k (l_s - l_s0), tension positive (eq. 19)"),
    ("tau_gravity", "N.m", "Gravity plus spring torque on the link about O, -dE_t/dtheta"),
    ("F_q", "N", "Spring's force on the carriage along +q"),
    ("F_lock", "N", "Screw's reaction on the carriage along +q beyond F_adjust: holding it at "
     "rest, its thread friction while it moves"),
    ("F_hold", "N", "Least actuator force that holds the carriage at rest: 0 on a self-locking "
     "screw, eta_b (m_q g - F_q) on a back-drivable one"),
    ("balance_error", "N.m", "(m c + payload w) g - x1A Y_B F_s / l_s; 0 when balanced "
     "(with X_B = 0, tau_gravity = balance_error sin(theta))"),
    ("E_p", "J", "Gravitational potential energy of link, payload and carriage"),
    ("E_e", "J", "Elastic energy of the spring, 1/2 k (l_s - l_s0 + F_s0/k)^2"),
    ("E_t", "J", "Total potential energy E_p + E_e"),
    ("E_kin", "J", "Kinetic energy of link, payload, carriage and both drive rotors"),
    ("W_drive", "J", "Cumulative work of tau_drive on the link"),
    ("W_adjust", "J", "Cumulative work of F_adjust on the screw (the actuator's mechanical "
     "work)"),
    ("E_loss", "J", "Energy dissipated so far (d_link, d_q, the screw's friction, payload "
     "catches)"),
    ("E_added", "J", "Energy brought in (taken out) by payload changes"),
)
# The inputs each output depends on directly (`physics.outputs`), its ModelStructure
# dependencies; an output not listed is a function of the state alone.
INPUT_DEPENDENCIES = {
    "tau_gravity": ("payload",),
    "balance_error": ("payload",),
    "E_p": ("payload",),
    "E_t": ("payload",),
    "E_kin": ("payload",),
    "F_lock": ("F_adjust",),
}


REGISTRATION = Registration(
    physics=physics,
    summary_outputs=("W_adjust",),
    ports=(Port(ANGULAR, "joint", "tau_drive", "omega", "theta"),
           Port(LINEAR, "carriage", "F_adjust", "q_dot", "q")),
    ledger={"E_t": 1, "E_kin": 1, "E_loss": 1, "W_drive": -1, "W_adjust": -1, "E_added": -1},
    # the screw's friction holds the carriage at rest: not one smooth ODE
    monolithic_reference=False,
    reference_run=rest_to_rest_move(
        {"tau_drive": (0.1, "N m"), "F_adjust": (0.5, "N")}, {"payload": 0.0},
        ("theta", "omega", "q", "Y_B", "F_q", "F_lock", "E_p", "E_kin", "W_adjust", "E_loss"),
        "; no payload: the balanced link swings while the self-locking screw holds the carriage "
        "(0.5 N is far below the force that lifts it through the thread's friction)"),
    moving_run=Run({}, {"tau_drive": 0.5, "F_adjust": 30.0, "payload": 0.5}, 2.0),
    # carriage pushed up against the spring while the link swings: the screw's force acts
    dependency_probes=(Run({}, {"tau_drive": 1.0, "F_adjust": 40.0, "payload": 0.5}, 0.3),),
)
