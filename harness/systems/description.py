"""The system of a scenario variant as data (`describe`): its FMUs, parameters and connections, and
the ECCO settings of a run with ECCO (see `harness.systems.system` for the system's shape)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from fmu_src.units.drive.dc_motor import armature_voltage
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu import osp
from harness.fmu.loader import CoSimFMU
from harness.run import master
from harness.run import scenario_files as scenarios
from harness.run.controller import ControllerDesign
from harness.run.drive import motors

# the component names of the system's FMUs
SEQUENCER, CONTROLLER, DRIVE, MECHANISM = "sequencer", "controller", "drive", "mechanism"
Value = float | bool | int

SYSTEM_DIR = fmu_build.DEFAULT_DEST.parent / "system"



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
            if not (value > 0.0 and np.isfinite(value)):
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


@dataclass(frozen=True)
class System:
    """A scenario variant as FMUs: components (name -> model and parameters), the FMU of
    each model, and connections (source component, output, destination component, input)."""

    scenario: scenarios.Scenario
    variant: scenarios.Variant
    step_size: float
    models: dict[str, str]
    parameters: dict[str, dict[str, Value]]
    connections: tuple[tuple[str, str, str, str], ...]
    fmus: dict[str, Path]
    ecco: EccoSettings | None = None   # None: libcosim's fixed step

    @property
    def name(self) -> str:
        return f"{self.scenario.name}_{self.variant.name}"

    @property
    def bonds(self) -> list[osp.PowerBond]:
        """The power bonds between the drives and the mechanism (osp.power_bonds)."""
        return osp.power_bonds(self.models, self.connections)


def controller(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's controller: `controller` or `controller_<joint>`."""
    return CONTROLLER + master.suffix(scenario, joint)


def drive(scenario: scenarios.Scenario, joint: scenarios.Joint) -> str:
    """The component name of a joint's drive: `drive` or `drive_<joint>`."""
    return DRIVE + master.suffix(scenario, joint)


def describe(scenario: scenarios.Scenario, variant: scenarios.Variant,
             step_size: float = master.DEFAULT_STEP,
             design: ControllerDesign = ControllerDesign(),
             ecco: EccoSettings | None = None) -> System:
    """The system of FMUs for a variant, with the harness's parameters and start (the
    ScenarioSequencer built for the scenario if build/fmus' one plays another). A variant's
    own joints get their controllers and drives too (`Scenario.for_variant`). ecco: run it
    with ECCO (step_size is then its first step), else at the fixed step."""
    scenario = scenario.for_variant(variant)
    drive_motors = [motors()[joint.motor] for joint in scenario.joints]
    model = variant.model or scenario.model
    mechanism_parameters = master.run_parameters(scenario, variant, drive_motors)
    inputs = {name: signal[0] for name, signal in
              scenario.inputs(np.zeros(1), variant).items()}
    # the variant by number: SSP tools read Integer parameters, not all read Strings
    number = list(scenario.variants).index(variant.name) + 1
    parameters: dict[str, dict[str, Value]] = {SEQUENCER: {"variant_number": number}}
    models = {SEQUENCER: fmu_build.SEQUENCER}
    connections = []
    with CoSimFMU(fmu_build.locate(model), f"{scenario.name}.{variant.name}.design") as fmu:
        fmu.set(inputs)
        fmu.initialize(mechanism_parameters, stop_time=scenario.duration)
        for joint, motor in zip(scenario.joints, drive_motors, strict=True):
            gains, hold_current = master.joint_drive(fmu, joint, motor, design)
            control, power = controller(scenario, joint), drive(scenario, joint)
            models |= {control: "PositionController", power: "DcMotorDrive"}
            parameters[control] = {**gains._asdict(), "V_supply": motor.V_supply,
                                   "integral0": armature_voltage(motor, hold_current, 0.0)}
            parameters[power] = {**asdict(motor), "i0": hold_current}
            connections += [(SEQUENCER, f"{joint.position}_ref", control, "theta_ref"),
                            (MECHANISM, joint.position, control, "theta"),
                            (control, "V", power, "V"),
                            (MECHANISM, joint.speed, power, "omega"),
                            (power, "tau_drive", MECHANISM, joint.effort)]
    models[MECHANISM] = model
    parameters[MECHANISM] = mechanism_parameters
    connections += [(SEQUENCER, name, MECHANISM, name) for name in inputs]
    fmus = {m: fmu_build.locate(m) for m in set(models.values()) - {fmu_build.SEQUENCER}}
    fmus[fmu_build.SEQUENCER] = sequencer_fmu(scenario)
    return System(scenario, variant, step_size, models, parameters, tuple(connections), fmus,
                  ecco)


def _plays(fmu: Path, scenario: scenarios.Scenario) -> bool:
    """Whether a ScenarioSequencer FMU plays this scenario (its description names it)."""
    from fmpy import read_model_description
    return f"plays scenario {scenario.name} " in (read_model_description(fmu).description or "")


def sequencer_fmu(scenario: scenarios.Scenario) -> Path:
    """A ScenarioSequencer FMU that plays the scenario: build/fmus' one if it does, else one
    built for the (shipped) scenario into build/system/<scenario>/fmus/, rebuilt when its
    inputs change (`fmu_build.fmu_path`): the one FMU a system builds, as it is part of the
    system's description."""
    default = fmu_build.locate(fmu_build.SEQUENCER)
    if _plays(default, scenario):
        return default
    source = scenarios.scenario_file(scenario.name)  # ValueError naming the known scenarios
    return fmu_build.fmu_path(fmu_build.SEQUENCER, SYSTEM_DIR / scenario.name / "fmus",
                              sequencer_scenario=source)
