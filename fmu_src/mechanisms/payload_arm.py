"""What the one-link payload arms share (CiupituBalancer, RockingCounterweightBalancer): the
slave base and the registration (standard library only); the variables every arm has are
`fmu_src.mechanisms.ciupitu.physics.ARM_OUTPUTS`."""

from __future__ import annotations

from typing import Any

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.fmi.vocabulary import DefaultExperiment
from fmu_src.mechanism import ANGULAR, Port, Registration, Run, one_link_panels, rest_to_rest_move


class PayloadArmSlave(MechanismSlave):
    """A one-link arm with a drive torque and a payload at distance w: inputs tau_drive and
    payload (physics.Inputs(tau_drive, payload)); the variables its physics declares."""

    # 1 ms is the harness's communication step; 20 s spans several strokes of a rocking
    # cycle and many periods of a default arm's free swing
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=20.0, step_size=1e-3)


def payload_arm(physics: Any, reference_outputs: tuple[str, ...], counterweight_position: str,
                **more: Any) -> Registration:
    """The registration of a one-link arm with a drive torque and a payload at distance w
    (`PayloadArmSlave`): its joint theta, the ledger E_p + E_kin + E_loss - W_drive
    - E_added, a rest-to-rest move without payload recording reference_outputs, a payload of
    2 kg that moves it, a probe with both inputs acting, and the one-link figure's panels
    (E_p, the payload and the output counterweight_position); more: further fields."""
    return Registration(
        physics=physics,
        ports=(Port(ANGULAR, "joint", "tau_drive", "omega", "theta"),),
        ledger={"E_p": 1, "E_kin": 1, "E_loss": 1, "W_drive": -1, "E_added": -1},
        reference_run=rest_to_rest_move({"tau_drive": (0.1, "N m")}, {"payload": 0.0},
                                        reference_outputs, "; no payload"),
        moving_run=Run({}, {"payload": 2.0}, 2.0),
        dependency_probes=(Run({}, {"tau_drive": 1.0, "payload": 0.5}, 0.3),),
        plot_panels=one_link_panels(("E_p",), (), (counterweight_position,)),
        **more)
