"""`python -m harness cross-check`: the FMUs in the layout of the FMI cross-check.

For every FMU of `harness.fmu_build.MODELS` it writes, under the destination folder,
`fmus/2.0/cs/<platform>/pythonfmu/<pythonfmu version>/<Model>/` with

- `<Model>.fmu`: the built FMU;
- `<Model>_in.csv`: its input signals, if it has inputs (every input; linear interpolation
  between rows, a repeated time is a step);
- `<Model>_ref.csv`: the reference result, simulated with FMPy (time, then up to ten
  recorded variables; Booleans as 0 and 1, which the cross-check's CSV reader takes as
  numbers);
- `<Model>_ref.opt`: StartTime, StopTime, StepSize, RelTol and OutputIntervalLength;
- `ReadMe.md`: what the model is and how the reference was made,

following the FMI cross-check rules (modelica/fmi-cross-check, FMI-CROSS-CHECK-RULES.md:
CSV conventions, files below 1 MB). The run is each model's reference run, the one its
documentation plots (`harness.fmu_docs.REFERENCE_RUNS`). Every file is written atomically;
the command then validates the folder as the cross-check CI does
(`fmpy.cross_check.validate_vendor_repo`) and returns the number of problems found.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import fmpy
import numpy as np
import pandas as pd
import pythonfmu
from fmpy import read_model_description
from fmpy.cross_check.validate_vendor_repo import validate_repo
from fmpy.model_description import ModelDescription

from harness import fmu_build, fmu_docs
from harness.results import write_atomic, write_csv

TOOL = "pythonfmu"
DEFAULT_DEST = fmu_build.DEFAULT_DEST.parent / "cross-check"


def model_dir(dest: Path, model: str) -> Path:
    """The folder of one exported FMU in the cross-check layout under dest."""
    return dest / "fmus" / "2.0" / "cs" / fmpy.platform / TOOL / pythonfmu.__version__ / model


def frame(table: np.ndarray) -> pd.DataFrame:
    """A structured array as a table with the same columns."""
    return pd.DataFrame({name: table[name] for name in table.dtype.names})


def ref_opt(md: ModelDescription, run: fmu_docs.ReferenceRun) -> str:
    """The <Model>_ref.opt file: the settings that reproduce the reference."""
    dt = fmu_docs.step_size(md)
    return (f"StartTime,0.0\nStopTime,{fmu_docs.stop_time(md, run)!r}\nStepSize,{dt!r}\n"
            f"RelTol,{fmu_docs.RELATIVE_TOLERANCE!r}\n"
            f"OutputIntervalLength,{fmu_docs.output_interval(md, run)!r}\n")


def readme(md: ModelDescription, run: fmu_docs.ReferenceRun) -> str:
    """The ReadMe.md of one exported FMU."""
    name = md.modelName
    inputs = ("the model has no inputs" if run.inputs is None else
              f"the inputs of `{name}_in.csv` interpolated linearly and applied at each "
              "communication point")
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


def export(model: str, dest: Path) -> Path:
    """Write the cross-check folder of one model under dest and return it."""
    fmu = fmu_build.fmu_path(model)
    md = read_model_description(str(fmu))
    run = fmu_docs.reference_run(model)
    folder = model_dir(dest, model)
    write_atomic(folder / f"{model}.fmu", lambda tmp: shutil.copyfile(fmu, tmp))
    if run.inputs is not None:
        write_csv(frame(run.inputs), folder / f"{model}_in.csv")
    write_csv(frame(fmu_docs.simulate_reference(fmu, run)), folder / f"{model}_ref.csv")
    write_atomic(folder / f"{model}_ref.opt", lambda tmp: tmp.write_text(ref_opt(md, run)))
    write_atomic(folder / "ReadMe.md", lambda tmp: tmp.write_text(readme(md, run)))
    return folder


COMMAND = "cross-check"
HELP = ("write every FMU with its reference result in the FMI cross-check layout "
        "(build/cross-check) and validate it")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--dest", type=Path, default=DEFAULT_DEST,
                        help="cross-check repository folder (fmus/ is written inside)")


def run(args: argparse.Namespace) -> int:
    for model in fmu_build.MODELS:
        print(export(model, args.dest))
    fmu_count, _, problems = validate_repo(str(args.dest.resolve()))
    print(f"validate_vendor_repo: {len(problems)} problems in {fmu_count} FMUs")
    for problem in problems:
        print(problem)
    return len(problems)
