"""The FMPy SSP engine: the variant's system of FMUs (`harness.engines.system`) written as an
.ssp archive into build/system/<scenario>/ and run by FMPy's `simulate_ssp`.

FMPy 0.3.32's `simulate_ssp`, compared with libcosim on this system:
- right: the connections, the fixed step, the Jacobi exchange;
- wrong, worked around here: it ignores the SSD's parameter bindings (they are passed as its
  `parameter_set` argument instead) and it reads Boolean literals as true whatever they say
  (values are passed as Python types). It cannot set String parameters either, which is one
  reason the sequencer's variant is bound by number (`variant_number`, an Integer), the
  other that OMSimulator reads no String binding;
- wrong, not worked around (it shows in the results): every connected input starts at 0.0
  instead of the source's start value, so in the first step the controller sees theta = 0
  and the mechanism gets tau_drive = 0; and the rows are stamped with the time at the start
  of the step although they hold the values at its end (corrected here when recording).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pandas as pd

from harness.engines.plan import RunPlan
from harness.engines.result import RunResult
from harness.engines.system import (
    MECHANISM,
    SEQUENCER,
    SYSTEM_DIR,
    System,
    controller,
    describe,
    drive,
    recorded_every,
    system_result,
)
from harness.engines.writers import write_ssp


def run(plan: RunPlan, progress: Callable[[int], None] | None = None) -> RunResult:
    """The planned run's system run by FMPy's SSP runner at the fixed step, from its SSP
    archive (build/system/<scenario>/<variant>.ssp)."""
    system = describe(plan)
    result = run_fmpy_ssp(system, write_ssp(system, SYSTEM_DIR / plan.scenario.name /
                                            f"{plan.variant.name}.ssp"))
    if progress is not None:
        progress(plan.n_steps)
    return result


def run_fmpy_ssp(system: System, ssp: Path) -> RunResult:
    """Run the SSP archive with fmpy.ssp.simulate_ssp, which returns every connector after
    every step (stamped with the step's start time). It has no row for t = 0: that row is
    the start the system is built for (the scenario's initial position, inputs and
    reference; the drive holding i0) and the mechanism's other outputs after the first step.
    """
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import Parameter, ParameterSet

    parameter_set = ParameterSet(name="bindings")
    for component, values in system.parameters.items():
        for name, value in values.items():
            parameter_set.parameters.append(Parameter(name=f"{component}.{name}", value=value))
    table = simulate_ssp(str(ssp), stop_time=system.scenario.duration,
                         step_size=system.step_size, parameter_set=parameter_set)
    frame = pd.DataFrame({name: table[name] for name in table.dtype.names[1:]})
    scenario = system.scenario
    start = frame.iloc[[0]].copy()
    start_inputs = system.plan.inputs
    for joint, initial in zip(scenario.joints, scenario.initial_angle, strict=True):
        start[f"{MECHANISM}.{joint.position}"] = initial
        start[f"{SEQUENCER}.{joint.position}_ref"] = initial
        start[f"{controller(scenario, joint)}.V"] = 0.0   # FMPy: connected inputs start at 0
        start[f"{drive(scenario, joint)}.tau_drive"] = 0.0
    for name, signal in start_inputs.items():
        start[f"{MECHANISM}.{name}"] = signal[0]
    frame = pd.concat([start, frame], ignore_index=True)
    every = recorded_every(system)
    booleans = pd.DataFrame({c.split(".", 1)[1]: frame[c].iloc[::every].to_numpy()
                             for c in frame if c.startswith(f"{MECHANISM}.")
                             and frame[c].dtype == bool})
    return system_result(system, frame, booleans, [])
