"""Trivial pythonfmu slave for the benchmark floor: the cost of FMI and the embedded interpreter.

One Real input, one Real output; do_step only copies the input to the output.
"""

from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class BenchFloor(Fmi2Slave):
    """Copies its input u to its output y at every communication step."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = "Benchmark floor: y = u, nothing else"
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="Input copied to y"))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.exact, description="Copy of u"))

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.y = self.u
        return True
