"""A slave whose class defines no method of its own: everything is inherited from _Base.

pythonfmu's builder picks the Fmi2Slave subclass with the longest hierarchy, so the FMU's
class is NoMethodsOfItsOwn; the runtime must find __init__ and do_step through the MRO.
"""

from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class _Base(Fmi2Slave):
    """One Real output, the simulation time."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.t = 0.0
        self.register_variable(Real("t", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.exact,
                                    description="Time at the end of the last step"))

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.t = current_time + step_size
        return True


class NoMethodsOfItsOwn(_Base):
    """Everything inherited."""
