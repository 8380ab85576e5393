"""The engines that run a scenario variant, behind one seam: each is a function
(scenario, variant, step_size [s], progress=None, **options) -> RunResult
(`harness.engines.result`), and ENGINES names them. Adding an engine (FMI 3, Model Exchange,
a distributed co-simulation) is one module and one line here.

An engine's module is imported when it is first called, so that naming the engines costs
nothing and an engine whose package is not installed (libcosimpy comes with the `dev`
extra) fails only when it is used.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from harness.engines.result import RunResult
from harness.scenarios import Scenario, Variant

DEFAULT_STEP = 1e-3  # communication step [s]


@dataclass(frozen=True)
class Engine:
    """An engine: the function `module.function` and what it is; options: the keyword
    options it takes beyond the seam's arguments (the command line's engine options)."""

    module: str
    function: str
    help: str
    options: tuple[str, ...] = ()

    def supports(self, model: str) -> bool:
        """Whether the engine can run the model: its module's `supports(model)`, where it
        has one (the monolithic reference needs the mechanism's physics), else True."""
        supports = getattr(importlib.import_module(self.module), "supports", None)
        return supports is None or supports(model)

    def __call__(self, scenario: Scenario, variant: Variant, step_size: float,
                 progress: Callable[[int], None] | None = None, **options: Any) -> RunResult:
        run = getattr(importlib.import_module(self.module), self.function)
        return run(scenario, variant, step_size, progress, **options)


ENGINES = {
    "fmpy": Engine("harness.engines.fmpy_master", "run",
                   "the mechanism FMU in FMPy, with the drives and controllers in this "
                   "process (the committed results)"),
    "reference": Engine("harness.engines.reference", "run",
                        "the monolithic reference: the whole system as one ODE in scipy's "
                        "solve_ivp, continuous controllers, no FMI"),
    "libcosim": Engine("harness.engines.libcosim", "run",
                       "the system of FMUs (sequencer, controllers, drives, mechanism) in "
                       "DNV's libcosim at the fixed step, from OSP or SSP files",
                       ("source",)),
    "libcosim-ecco": Engine("harness.engines.libcosim", "run_ecco",
                            "the system of FMUs in libcosim under ECCO, the step adapted to "
                            "the power bonds' energy residuals", ("ecco",)),
    "fmpy-ssp": Engine("harness.engines.fmpy_ssp", "run",
                       "the system of FMUs as an SSP archive in FMPy's SSP runner"),
    "fmu-me": Engine("harness.engines.fmu_me", "run",
                     "the mechanism FMU as FMI 2.0 Model Exchange, integrated with the "
                     "drives' ODE by scipy's solve_ivp, its state events included"),
}
