"""Probe slave for the FMUs' C runtime (tests/test_runtime.py): each failure path on demand.

The Integer input `mode` selects what do_step does:

0. normal: y = gain * u, return True
1. raise ValueError (a message with printf directives: the runtime must pass it as text)
2. raise MemoryError (the runtime answers fmi2Fatal)
3. return False (fmi2Discard)
4. log a Warning with printf directives, then as 0
"""

from typing import Any

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status

VALUE_ERROR = "probe: value error 100 % sure %s %n"
PRINTF_MESSAGE = "probe: 70.7 % of the gravity moment, %s %n %d"


class RuntimeProbe(Fmi2Slave):
    """y follows u; `mode` makes do_step fail in each of the ways a slave can."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.description = "Probe of the FMI runtime's failure paths"
        self.u = 0.0
        self.y = 0.0
        self.gain = 1.0
        self.mode = 0
        self.text = "initial"
        self.flag = False
        self.steps = 0
        self.register_variable(Real("u", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous,
                                    description="Input copied to y"))
        self.register_variable(Real("y", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.exact, description="gain * u"))
        self.register_variable(Integer("mode", causality=Fmi2Causality.input,
                                       variability=Fmi2Variability.discrete,
                                       description="What do_step does (module docstring)"))
        self.register_variable(Real("gain", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed,
                                    initial=Fmi2Initial.exact, description="y / u"))
        self.register_variable(String("text", causality=Fmi2Causality.output,
                                      variability=Fmi2Variability.discrete,
                                      initial=Fmi2Initial.exact,
                                      description="The number of steps taken, as text"))
        self.register_variable(Boolean("flag", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete,
                                       initial=Fmi2Initial.exact,
                                       description="True after an odd number of steps"))

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self.mode == 1:
            raise ValueError(VALUE_ERROR)
        if self.mode == 2:
            raise MemoryError()
        if self.mode == 3:
            return False
        if self.mode == 4:
            self.log(PRINTF_MESSAGE, Fmi2Status.warning)
        self.steps += 1
        self.y = self.gain * self.u
        self.text = f"{self.steps} steps"
        self.flag = self.steps % 2 == 1
        return True
