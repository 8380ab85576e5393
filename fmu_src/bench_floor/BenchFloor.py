"""Trivial slave for the benchmark floor: the cost of FMI and the embedded interpreter.

One Real input, one Real output; do_step only copies the input to the output. It stands on
the bare adaptor of the FMI version the slaves are bound to (`fmu_src.fmi.binding`, pythonfmu's
Fmi2Slave for FMI 2.0), with none of the model slaves' checks.
"""

from typing import Any

from fmu_src.fmi.binding import Adaptor
from fmu_src.fmi.vocabulary import Causality, Initial, ValueType, Variability


class BenchFloor(Adaptor):
    """Copies its input u to its output y at every communication step."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = "Benchmark floor: y = u, nothing else"
        self.u = 0.0
        self.y = 0.0
        self.declare(ValueType.real, "u", Causality.input, Variability.continuous,
                     "Input copied to y")
        self.declare(ValueType.real, "y", Causality.output, Variability.continuous,
                     "Copy of u", Initial.exact)

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.y = self.u
        return True
