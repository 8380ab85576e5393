"""`python -m harness cross-check`: the FMUs in the layout of the FMI cross-check.

For every FMU of `harness.fmu.build.MODELS` it writes, under the destination folder,
`fmus/2.0/cs/<platform>/pythonfmu/<pythonfmu version>/<Model>/`, and for an FMU that offers
Model Exchange (the mechanisms) the same under `fmus/2.0/me/` with the reference simulated
as Model Exchange (FMPy's CVode), with

- `<Model>.fmu`: a copy of build/fmus' FMU (`make fmu` builds it, `fmu_build.locate`), so
  the cross-check publishes the very FMU (bytes and GUID) the other commands use;
- `<Model>_in.csv`: its input signals, if it has inputs (every input; linear interpolation
  between rows). A step is written as a ramp over the communication step before it
  (`importer_inputs`), not as a repeated time: an importer that samples the inputs at its
  communication points then reads the same values whether its clock lands a little before or
  after them (fmuCheck accumulates t += h and lands on either side; with a repeated time at
  a communication point it applied the step there or one step later);
- `<Model>_ref.csv`: the reference result, simulated with FMPy (time, then up to ten
  recorded variables; Booleans as 0 and 1, which the cross-check's CSV reader takes as
  numbers);
- `<Model>_ref.opt`: StartTime, StopTime, StepSize, RelTol and OutputIntervalLength;
- `ReadMe.md`: what the model is and how the reference was made,

following the FMI cross-check rules (modelica/fmi-cross-check, FMI-CROSS-CHECK-RULES.md:
CSV conventions, files below 1 MB). The run is each model's reference run, the one its
documentation plots (`harness.fmu.docs.reference_run`). Every file is written atomically;
the command then validates the folder as the cross-check CI does
(`fmpy.cross_check.validate_vendor_repo`) and returns the number of problems found.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import fmpy
import numpy as np
import pythonfmu
from fmpy import read_model_description
from fmpy.model_description import ModelDescription

from harness.fmu import build as fmu_build
from harness.fmu import docs as fmu_docs
from harness.io import write_atomic, write_csv

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["export", "importer_inputs", "model_dir"]

TOOL = "pythonfmu"
DEFAULT_DEST = fmu_build.DEFAULT_DEST.parent / "cross-check"


# the cross-check's folder of each FMI interface, and FMPy's name of it
INTERFACES = {"cs": "CoSimulation", "me": "ModelExchange"}


def model_dir(dest: Path, model: str, interface: str = "cs") -> Path:
    """The folder of one exported FMU in the cross-check layout under dest, for the
    interface "cs" (Co-Simulation) or "me" (Model Exchange)."""
    return (dest / "fmus" / "2.0" / interface / fmpy.platform / TOOL / pythonfmu.__version__
            / model)


def frame(table: np.ndarray) -> pd.DataFrame:
    """A structured array as a table with the same columns."""
    import pandas as pd

    return pd.DataFrame({name: table[name] for name in table.dtype.names})


def importer_inputs(table: np.ndarray, step: float) -> np.ndarray:
    """The input table with every step (rows (t, a), (t, b)) made a ramp over the
    communication step before t: rows (t - step, u(t - step)), (t, b), where u(t - step)
    lies on the segment that led to a (no row is added when one is already there).

    At every communication point the inputs keep the values FMPy applies from the original
    table (b from t on: it applies the right-hand value at an event), and no time repeats:
    FMPy, which shortens a step to end on an input event, steps as a fixed-step importer
    does, and an importer whose clock lands a little off a communication point reads nearly
    the same values (for a clock error e, (b - a) e / step), not a or b by rounding.
    ValueError if a step lies within one communication step of the row before it.
    """
    rows = [tuple(float(v) for v in row) for row in table]
    out = [rows[0]]
    for i in range(1, len(rows)):
        t, before = rows[i][0], rows[i - 1]
        if i + 1 < len(rows) and rows[i + 1][0] == t:       # (t, a) of a step
            start = t - step
            if np.isclose(start, before[0], rtol=0.0, atol=1e-9 * step):
                continue                                     # a row is there already
            if start < before[0]:
                raise ValueError(f"input step at t = {t} s lies within one communication "
                                 f"step ({step} s) of the row at {before[0]} s")
            weight = (start - before[0]) / (t - before[0])
            out.append((start, *(u0 + weight * (u1 - u0)
                                 for u0, u1 in zip(before[1:], rows[i][1:], strict=True))))
        else:                                                # (t, b) of a step, or a plain row
            out.append(rows[i])
    return np.array(out, dtype=table.dtype)


def ref_opt(md: ModelDescription, run: fmu_docs.ReferenceRun, interface: str = "cs") -> str:
    """The <Model>_ref.opt file: the settings that reproduce the reference."""
    dt = fmu_docs.step_size(md)
    tolerance = (fmu_docs.RELATIVE_TOLERANCE if interface == "cs"
                 else fmu_docs.ME_RELATIVE_TOLERANCE)
    return (f"StartTime,0.0\nStopTime,{fmu_docs.stop_time(md, run)!r}\nStepSize,{dt!r}\n"
            f"RelTol,{tolerance!r}\n"
            f"OutputIntervalLength,{fmu_docs.output_interval(md, run)!r}\n")


def readme(md: ModelDescription, run: fmu_docs.ReferenceRun, interface: str = "cs") -> str:
    """The ReadMe.md of one exported FMU."""
    if interface == "me":
        return model_exchange_readme(md, run)
    name = md.modelName
    inputs = ("the model has no inputs" if run.inputs is None else
              f"the inputs of `{name}_in.csv` interpolated linearly and applied at each "
              "communication point (a step is a ramp over the communication step before the "
              "point from which it applies, so that no discontinuity falls on a "
              "communication point)")
    return f"""# {name}

{md.description}

FMI 2.0 Co-Simulation FMU exported with PythonFMU {pythonfmu.__version__} by the gravity
balancer co-simulation project (`python -m harness cross-check`). Equations, variables with
units and start values, and a plot of the reference result are in the FMU's
`documentation/index.html`.

## Reference result

{run.description}

`{name}_ref.csv` was simulated with FMPy {fmpy.__version__} with the settings of
`{name}_ref.opt`: a fixed communication step of StepSize, {inputs}, results
recorded every OutputIntervalLength (Booleans as 0 and 1). The model steps with its own
fixed schemes (RelTol is passed to fmi2SetupExperiment but unused).

## Requirements

The FMU runs Python code (standard library only) in an embedded interpreter: the machine
needs a CPython 3.8 or later shared library (built with Python
{sys.version_info.major}.{sys.version_info.minor}).
The linux64 binary loads it by itself in a host that is not a Python process (the one the FMU
was built with, or the file named by the environment variable BALANCER_FMU_LIBPYTHON) and
needs glibc 2.32 and the GCC 12 C++ runtime.
"""


def model_exchange_readme(md: ModelDescription, run: fmu_docs.ReferenceRun) -> str:
    """The ReadMe.md of one FMU exported as Model Exchange."""
    name = md.modelName
    return f"""# {name} (Model Exchange)

{md.description}

The FMU of `../../../../cs/` (the same file: one model description offers Co-Simulation and
Model Exchange), exported by the gravity balancer co-simulation project (`python -m harness
cross-check`). Its continuous states are the mechanism's state with its energy account
(W_drive, E_loss, E_added, ...); its {md.numberOfEventIndicators} event indicators are its
end stops and regime changes (docs/model_exchange.md of the project).

## Reference result

{run.description}

`{name}_ref.csv` was simulated with FMPy {fmpy.__version__}'s CVode at the relative tolerance
RelTol of `{name}_ref.opt`, the inputs of `{name}_in.csv` (a repeated time is a step: an
event), results recorded every OutputIntervalLength.

## Requirements

As for Co-Simulation: a CPython 3.8 or later shared library, which the linux64 binary loads by
itself in a host that is not a Python process (needsExecutionTool is false).
"""


def export(model: str, dest: Path) -> list[Path]:
    """Write the cross-check folders of one model under dest (Co-Simulation, and Model
    Exchange where the FMU offers it) and return them."""
    fmu = fmu_build.locate(model)
    md = read_model_description(str(fmu))
    steps = fmu_docs.reference_run(model)
    folders = []
    for interface, fmi_type in INTERFACES.items():
        if interface == "me" and md.modelExchange is None:
            continue
        # Co-Simulation: a step as a ramp over the communication step before it (see
        # importer_inputs); Model Exchange: a step as it is, a time event, so that the
        # solver integrates with the inputs constant between events (FMPy's CVode sets a
        # continuous input only where it checks its event indicators: a ramp would change
        # the right-hand side behind the solver's back)
        run = (replace(steps, inputs=importer_inputs(steps.inputs, fmu_docs.step_size(md)))
               if interface == "cs" and steps.inputs is not None else steps)
        folder = model_dir(dest, model, interface)
        write_atomic(folder / f"{model}.fmu", lambda tmp: shutil.copyfile(fmu, tmp))
        if run.inputs is not None:
            write_csv(frame(run.inputs), folder / f"{model}_in.csv")
        write_csv(frame(fmu_docs.simulate_reference(fmu, run, fmi_type)),
                  folder / f"{model}_ref.csv")
        options, notes = ref_opt(md, run, interface), readme(md, run, interface)
        write_atomic(folder / f"{model}_ref.opt", lambda tmp, text=options: tmp.write_text(text))
        write_atomic(folder / "ReadMe.md", lambda tmp, text=notes: tmp.write_text(text))
        folders.append(folder)
    return folders


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=DEFAULT_DEST, metavar="DIR",
                        help="cross-check repository folder (fmus/ is written inside)")


def run(args: argparse.Namespace) -> int:
    for model in fmu_build.MODELS:
        for folder in export(model, args.out):
            print(folder)
    from fmpy.cross_check.validate_vendor_repo import validate_repo

    fmu_count, _, problems = validate_repo(str(args.out.resolve()))
    print(f"validate_vendor_repo: {len(problems)} problems in {fmu_count} FMUs")
    for problem in problems:
        print(problem)
    return len(problems)
