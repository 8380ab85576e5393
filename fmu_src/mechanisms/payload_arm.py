"""What the one-link payload arms share (CiupituBalancer, RockingCounterweightBalancer): the
slave base with the inputs tau_drive and payload and the output rows every arm has, and their
registration (standard library only)."""

from __future__ import annotations

from typing import Any

from pythonfmu.default_experiment import DefaultExperiment

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.mechanism import ANGULAR, Port, Registration, Run, rest_to_rest_move

# The output rows every payload arm has (PayloadArmSlave.output_table), by name.
ARM_OUTPUTS = {row[0]: row for row in (
    ("theta", "rad", "Arm angle from the upward vertical, counter-clockwise positive "
                     "(the paper's phi = pi/2 - theta)"),
    ("omega", "rad/s", "Arm angular velocity"),
    ("E_p", "J", "Gravitational potential energy of link, payload and both counterweights"),
    ("E_kin", "J", "Kinetic energy of link, payload, counterweights and drive rotor"),
    ("M_g", "N.m", "Payload moment about O, -payload g w cos(phi) (eq. 8, paper's sign)"),
    ("M_u", "N.m", "Unbalanced moment M_b + M_g (eq. 16)"),
    ("W_drive", "J", "Cumulative work of tau_drive on the arm"),
    ("E_loss", "J", "Cumulative energy dissipated: pivot friction, payload picked up while "
                    "moving"),
    ("E_added", "J", "Cumulative energy brought in (+) or taken out (-) by payload joining or "
                     "leaving; E_p + E_kin + E_loss - W_drive - E_added is constant"),
)}


class PayloadArmSlave(MechanismSlave):
    """A one-link arm with a drive torque and a payload at distance w: inputs tau_drive and
    payload (physics.Inputs(tau_drive, payload)); outputs from the subclass's table."""

    # (name, unit, description) per output (ARM_OUTPUTS has the rows every arm shares), and
    # the inputs each depends on (ModelStructure): the payload's moment, inertia and weight
    output_table: tuple[tuple[str, str, str], ...] = ()
    input_dependencies: dict[str, tuple[str, ...]] = {
        name: ("payload",) for name in ("tau_gravity", "E_p", "E_kin", "M_g", "M_u")}
    # 1 ms is the harness's communication step; 20 s spans several strokes of a rocking
    # cycle and many periods of a default arm's free swing
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.add_input("tau_drive", 0.0, "N.m", "Drive torque on the arm about O, along theta")
        self.add_input("payload", 0.0, "kg", "Payload mass at distance w (the paper's G_pv/g)",
                       min=0.0)
        for name, unit, description in self.output_table:
            self.add_output(name, unit, description, self.input_dependencies.get(name, ()))


def payload_arm(physics: Any, reference_outputs: tuple[str, ...], **more: Any) -> Registration:
    """The registration of a one-link arm with a drive torque and a payload at distance w
    (`PayloadArmSlave`): its joint theta, the ledger E_p + E_kin + E_loss - W_drive
    - E_added, a rest-to-rest move without payload recording reference_outputs, a payload of
    2 kg that moves it, and a probe with both inputs acting; more: further fields."""
    return Registration(
        physics=physics,
        ports=(Port(ANGULAR, "joint", "tau_drive", "omega", "theta"),),
        ledger={"E_p": 1, "E_kin": 1, "E_loss": 1, "W_drive": -1, "E_added": -1},
        reference_run=rest_to_rest_move({"tau_drive": (0.1, "N m")}, {"payload": 0.0},
                                        reference_outputs, "; no payload"),
        moving_run=Run({}, {"payload": 2.0}, 2.0),
        dependency_probes=(Run({}, {"tau_drive": 1.0, "payload": 0.5}, 0.3),),
        **more)
