"""FMI 2.0 Co-Simulation slave of the spring balancer with an actively relocated frame joint
(Ciupitu 2018, Fig. 8).

A thin layer over `fmu_src.mechanisms.active_spring.physics` (the common plumbing is
`MechanismSlave`'s); it warns through the FMU log when the spring is compressed (the model's
linear force law pushes there, which an extension spring cannot). """

from __future__ import annotations

from typing import Any

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.fmi.vocabulary import DefaultExperiment
from fmu_src.mechanism import (
    ANGULAR,
    LINEAR,
    Port,
    Registration,
    Run,
    one_link_panels,
    rest_to_rest_move,
)
from fmu_src.mechanisms.active_spring import physics


class ActiveSpringBalancer(MechanismSlave):
    """1-DOF link balanced by a spring whose frame joint a prismatic joint, driven through a
    screw with thread friction, moves along the vertical (Ciupitu 2018, Section 3)."""

    physics = physics
    hidden_state = (*MechanismSlave.hidden_state, "compression_reported")
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=5.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = ("Spring gravity balancer with active relocation of the spring's "
                            "frame joint by one prismatic joint on a screw with thread "
                            "friction, self-locking by default (Ciupitu 2018, Fig. 8)")
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
    plot_panels=one_link_panels(("E_p", "E_e", "E_t"), ("q",), ("l_s",)),
)
