"""The engines that run a scenario variant, behind one seam: a run is planned once
(`harness.engines.plan.prepare` -> `RunPlan`) and an engine is a function
(plan, progress=None, **options) -> RunResult (`harness.engines.result`); ENGINES names
them. Adding an engine (FMI 3, a distributed co-simulation) is one module and one line here;
a drive change is made in `harness.drive` and reaches every engine through the plan.

An engine's module is imported when it is first called, so that an engine whose package is
not installed (libcosimpy comes with the `dev` extra) fails only when it is used.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from harness.engines.settings import DEFAULT_STEP

if TYPE_CHECKING:  # the registry imports no engine, nor what an engine needs
    from harness.drive.controller import ControllerDesign
    from harness.engines.plan import Drives, Motors, RunPlan
    from harness.engines.result import RunResult
    from harness.scenarios import Scenario, Variant

__all__ = ["DEFAULT_STEP", "ENGINES", "Engine", "run"]


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

    def __call__(self, plan: RunPlan, progress: Callable[[int], None] | None = None,
                 **options: Any) -> RunResult:
        return getattr(importlib.import_module(self.module), self.function)(
            plan, progress, **options)


ENGINES = {
    "fmpy": Engine("harness.engines.fmpy_master", "run",
                   "the mechanism FMU in FMPy, with the drives and controllers in this "
                   "process (the committed results)"),
    "reference": Engine("harness.engines.reference", "run",
                        "the monolithic reference: the whole system as one ODE in scipy's "
                        "solve_ivp, continuous controllers, no FMI"),
    "fmu-me": Engine("harness.engines.fmu_me", "run",
                     "the mechanism FMU as FMI 2.0 Model Exchange, integrated with the "
                     "drives' ODE by scipy's solve_ivp, its state events included"),
    "libcosim": Engine("harness.engines.libcosim", "run",
                       "the system of FMUs (sequencer, controllers, drives, mechanism) in "
                       "DNV's libcosim at the fixed step, from OSP or SSP files",
                       ("source",)),
    "libcosim-ecco": Engine("harness.engines.libcosim", "run_ecco",
                            "the system of FMUs in libcosim under ECCO, the step adapted to "
                            "the power bonds' energy residuals", ("ecco",)),
    "fmpy-ssp": Engine("harness.engines.fmpy_ssp", "run",
                       "the system of FMUs as an SSP archive in FMPy's SSP runner"),
}


def run(engine: str, scenario: Scenario, variant: Variant, step_size: float = DEFAULT_STEP,
        progress: Callable[[int], None] | None = None, drives: Drives = None,
        motor: Motors = None, design: ControllerDesign | None = None,
        **options: Any) -> RunResult:
    """One run of the variant in the named engine: its plan (`prepare`, with the drives,
    motor and design, by default `ControllerDesign()`), then the engine with its options."""
    from harness.drive.controller import ControllerDesign
    from harness.engines.plan import prepare

    plan = prepare(scenario, variant, step_size, drives, motor, design or ControllerDesign())
    return ENGINES[engine](plan, progress, **options)
