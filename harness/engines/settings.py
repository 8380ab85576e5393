"""The engines' own settings, which the command line offers without importing an engine
(`harness.run.cosim`): the default communication step, the description a fixed-step
libcosim run reads, and ECCO's step-size controller."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from harness.errors import UserError

DEFAULT_STEP = 1e-3  # communication step [s]
SOURCES = ("osp", "ssp")  # the fixed-step run's description: OspSystemStructure.xml or .ssp


@dataclass(frozen=True)
class EccoSettings:
    """libcosim's ECCO algorithm (Sadjina et al. 2017): after each step it takes the power
    each side of every power bond sees (its held input times its new output), and sizes the
    next step with a PI controller on the bonds' energy residuals |P_a - P_b| h, scaled by
    abs_tolerance + rel_tolerance max|P_a - P_b| h; no step is rejected. Times in s,
    tolerances in J."""

    abs_tolerance: float = 1e-7
    rel_tolerance: float = 1e-4
    min_step: float = 1e-4
    max_step: float = 1e-2
    safety_factor: float = 0.8
    # the factor the step may change by at once, min and max (libcosim's own test data)
    min_change_rate: float = 0.2
    max_change_rate: float = 1.5
    p_gain: float = 0.2
    i_gain: float = 0.15

    def check(self) -> None:
        """UserError naming the first setting outside its range."""
        for name, value in asdict(self).items():
            if not (value > 0.0 and math.isfinite(value)):
                raise UserError(f"ECCO {name} = {value} is outside (0, inf)")
        if self.min_step > self.max_step:
            raise UserError(f"ECCO min_step = {self.min_step} s exceeds max_step = "
                            f"{self.max_step} s")
        if self.min_change_rate > 1.0 or self.max_change_rate < 1.0:
            raise UserError(f"ECCO change rates [{self.min_change_rate}, "
                            f"{self.max_change_rate}] must hold 1")

    def osp_elements(self, initial_step: float) -> dict[str, float]:
        """The EccoConfiguration elements of an OspSystemStructure.xml, by tag."""
        return {"SafetyFactor": self.safety_factor,
                "StepSize": min(max(initial_step, self.min_step), self.max_step),
                "MinimumStepSize": self.min_step, "MaximumStepSize": self.max_step,
                "MinimumChangeRate": self.min_change_rate,
                "MaximumChangeRate": self.max_change_rate,
                "ProportionalGain": self.p_gain, "IntegralGain": self.i_gain,
                "RelativeTolerance": self.rel_tolerance,
                "AbsoluteTolerance": self.abs_tolerance}
