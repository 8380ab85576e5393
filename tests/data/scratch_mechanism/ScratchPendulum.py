"""FMI 2.0 Co-Simulation slave of the scratch mechanism (`fmu_src.mechanisms.pendulum.physics`)."""

from __future__ import annotations

from typing import Any

from fmu_src.mechanisms.pendulum import physics

from fmu_src.fmi.mechanism_slave import MechanismSlave
from fmu_src.fmi.vocabulary import DefaultExperiment
from fmu_src.mechanism import ANGULAR, Port, Registration, Run, rest_to_rest_move


class ScratchPendulum(MechanismSlave):
    """A damped pendulum driven at its pivot."""

    physics = physics
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=5.0, step_size=1e-3)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = "Damped pendulum (scratch mechanism of the registry test)"


REGISTRATION = Registration(
    physics=physics,
    ports=(Port(ANGULAR, "joint", "tau_drive", "omega", "theta"),),
    ledger={"E_p": 1, "E_kin": 1, "E_loss": 1, "W_drive": -1},
    reference_run=rest_to_rest_move({"tau_drive": (0.5, "N m")}, {}, ("theta", "omega", "E_p")),
    moving_run=Run({"theta0": 1.0}, duration=2.0),
    dependency_probes=(Run({}, {"tau_drive": 1.0}, 0.3),),
)
