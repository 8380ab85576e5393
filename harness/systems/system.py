"""`python -m harness system`: the task as a system of FMUs, described in SSP and OSP and run
by DNV's libcosim or by FMPy's SSP runner, with results in the harness's format.

The system of a scenario variant, per joint (a one-joint scenario such as franchetti2021):

    sequencer (ScenarioSequencer) --theta_ref--> controller (PositionController) --V--> drive
    (DcMotorDrive) --tau_drive--> mechanism (the variant's model) --theta--> controller,
    --omega--> drive; sequencer --payload, locks, ...--> mechanism.

With several joints (demian2022) each joint has its own controller and drive, named
`controller_<joint>` and `drive_<joint>`, wired to that joint's position, speed and effort.
The ScenarioSequencer FMU plays the scenario it was built for: build/fmus' one when it plays
the scenario (franchetti2021 by default), else one built for the scenario into
build/system/<scenario>/fmus/.

Its parameters are the harness's: the mechanism's scenario and variant parameters, the motor
defaults (harness.run.drive), the PID gains designed for the joint (harness.run.controller) and the
equilibrium start (motor current and integrator holding the static load at t = 0), bound in
the SSP's SystemStructure.ssd (inline ssv:ParameterSet per component) and as InitialValues
in OspSystemStructure.xml.

Both masters step every FMU in parallel (Jacobi) at the fixed step: each connection passes a
value with one step of delay, where the harness's loop (controller, motor, mechanism in
turn) has none. The loop thus carries two more steps of delay; at 1 ms that changes the
drive energies by less than the tolerances of tests/test_system.py. With `--algorithm ecco`
libcosim's ECCO steps the same Jacobi exchange at a step it adapts to the energy residuals
of the power bonds between each drive and its joint (`EccoSettings`, `ecco_execution`,
docs/results.md#variable-steps-ecco).

FMPy 0.3.32's `simulate_ssp` (engine `fmpy-ssp`), compared with libcosim on this system:
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

import argparse
from pathlib import Path

from tqdm import tqdm

from harness.errors import UserError
from harness.run import cosim, master, results
from harness.run import scenario_files as scenarios
from harness.systems.description import SYSTEM_DIR, EccoSettings, describe
from harness.systems.engines import run_fmpy_ssp, run_libcosim
from harness.systems.writers import write_osp, write_ssp

ENGINES = ("libcosim", "fmpy-ssp")

ALGORITHMS = ("fixed", "ecco")

def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--engine", choices=ENGINES, default="libcosim",
                        help="the master that runs the system")
    parser.add_argument("--scenario", default="franchetti2021",
                        help=f"shipped scenario ({', '.join(scenarios.available())})")
    parser.add_argument("--variants", dest="variant", default="all", metavar="VARIANTS",
                        help="'all' or a comma-separated list (eps baselines are added)")
    parser.add_argument("--variant", dest="variant", default=argparse.SUPPRESS,
                        help=argparse.SUPPRESS)  # hidden alias, for existing scripts
    parser.add_argument("--step", type=float, default=master.DEFAULT_STEP,
                        help="communication step [s] (default 1e-3)")
    parser.add_argument("--source", choices=("osp", "ssp"), default="osp",
                        help="libcosim: run OspSystemStructure.xml (default) or the .ssp")
    parser.add_argument("--out", type=Path, help="results folder (default "
                        "build/system/<scenario>/<engine>, <engine>-ecco with ECCO); SSP "
                        "and OSP files go to build/system/<scenario>/")
    parser.add_argument("--algorithm", choices=ALGORITHMS, default="fixed",
                        help="libcosim: the fixed step (default) or ECCO, whose step adapts "
                        "to the power bonds' energy residuals (--step is its first step)")
    defaults = EccoSettings()
    for name, unit, meaning in ECCO_OPTIONS:
        parser.add_argument(f"--ecco-{name.replace('_', '-')}", dest=f"ecco_{name}",
                            type=float, default=getattr(defaults, name), metavar="X",
                            help=f"ECCO: {meaning} (default {getattr(defaults, name)}"
                            f"{' ' + unit if unit else ''})")


# the ECCO settings as options: (field of EccoSettings, unit, meaning)
ECCO_OPTIONS = (
    ("abs_tolerance", "J", "absolute tolerance on a bond's energy residual per step"),
    ("rel_tolerance", "", "relative tolerance on it"),
    ("min_step", "s", "smallest step"),
    ("max_step", "s", "largest step"),
    ("safety_factor", "", "safety factor of the step controller"),
    ("min_change_rate", "", "smallest factor between two steps"),
    ("max_change_rate", "", "largest factor between two steps"),
    ("p_gain", "", "proportional gain of the step controller"),
    ("i_gain", "", "integral gain of the step controller"),
)


def check_ecco(ecco: EccoSettings | None, engine: str, source: str) -> None:
    """UserError for ECCO settings out of range, or ECCO asked of another engine or source."""
    if ecco is None:
        return
    ecco.check()
    if engine != "libcosim":
        raise UserError("--algorithm ecco runs only in --engine libcosim")
    if source != "osp":
        raise UserError("--algorithm ecco runs from the OSP description (--source osp): "
                        "the SSP archive has no power bonds")


def run_system(scenario: scenarios.Scenario, variants: list[str], engine: str,
               step_size: float, out: Path, source: str = "osp",
               ecco: EccoSettings | None = None) -> list[master.RunResult]:
    """Describe, write and run each variant's system (with ECCO: libcosim only, from the
    OSP file); write results into out."""
    if engine not in ENGINES:
        raise UserError(f"engine {engine!r} is not one of {', '.join(ENGINES)}")
    check_ecco(ecco, engine, source)
    runs = []
    for name in tqdm(variants, desc=f"{scenario.name} system ({engine})", unit="variant"):
        system = describe(scenario, scenario.variant(name), step_size, ecco=ecco)
        files = SYSTEM_DIR / scenario.name
        ssp = write_ssp(system, files / f"{name}.ssp")
        if engine == "fmpy-ssp":
            runs.append(run_fmpy_ssp(system, ssp))
        else:
            osp = write_osp(system, files / ("osp" if ecco is None else "osp-ecco") / name)
            # ECCO runs through the API (ecco_execution); its OSP file is for the cosim CLI
            runs.append(run_libcosim(system, None if ecco is not None
                                     else osp if source == "osp" else ssp))
    for path in results.write_run(runs, scenario, out):
        print(path)
    return runs


def run(args: argparse.Namespace) -> int:
    scenario = scenarios.load(args.scenario)
    scenario.check_step(args.step)  # the bounds of cosim and sweep
    variants = cosim.selected_variants(scenario, args.variant)
    ecco = None if args.algorithm == "fixed" else EccoSettings(
        **{name: getattr(args, f"ecco_{name}") for name, _, _ in ECCO_OPTIONS})
    check_ecco(ecco, args.engine, args.source)  # before the output folder is made
    out = args.out or SYSTEM_DIR / scenario.name / (
        args.engine if ecco is None else f"{args.engine}-ecco")
    results.check_writable(out)  # before the runs, not after them
    run_system(scenario, variants, args.engine, args.step, out, args.source, ecco)
    print(results.summary_text(out / "summary.csv", scenario))
    return 0
