"""Benchmarks: `python -m harness bench` writes one CSV per benchmark to results/bench/.

Each benchmark is a function (steps, repeats) -> table; BENCHMARKS maps the CSV name to it.

`fmu_step`: the cost of one communication step of SelfRegulatingBalancer stepped by FMPy,
with the calls the co-simulation master makes per step (harness.engines.fmpy_master: setReal
tau_drive, doStep, getReal theta and omega), next to the same loop over `BenchFloor`, a pythonfmu
FMU that only copies its input to its output, with pythonfmu's own binary: the floor that
pythonfmu imposes on any FMU made with it. `BenchFloorRuntime` is the same slave on our
runtime (fmu_src/runtime), as every FMU of the product is.

`native_step`: the same step loop (setReal, doStep, one getReal) of the floors and of each
mechanism FMU run by the C host of tests/native_host, as a tool that is not a Python process
runs it, against FMPy: CPU time per step of each and their ratio, and the C host's cost
against the stock floor's in the C host. Our FMUs run with an empty environment (the runtime
brings Python in); the stock floor as pythonfmu requires, libpython preloaded and PYTHONHOME
set.

`cosim`: wall time of every variant of every shipped scenario at 1 ms, as a real-time
factor (simulated / wall time), next to the cost of the FMU's own steps in it (steps times
the fmu_step cost): what the master, drive and controller add. `us_per_step` is the CPU time
of one closed-loop step in the thread that runs it (controller, motor, setReal, doStep,
getReal; the run's set-up and result assembly spread over its steps; not the spinning of
numerical libraries' helper threads) and `ratio_to_floor` its ratio to the BenchFloor step
measured in the same benchmark run, a figure that the machine's load moves much less than the
real-time factor. The last row is the sum, what `make cosim` spends in simulation on one
core.

`master_share`: per franchetti2021 variant, the CPU time of one closed-loop step (as `cosim`)
and that of its FMU calls (the master's loop, `harness.engines.fmpy_master.run_steps`,
replaying the run's efforts with no controller and no motor: the input changes and the
recording read included), best of repeats each, and their difference, the master's share
(also as a fraction of the step): its set-up and result assembly spread over the steps, and
the controller and motor. A reported figure, not a check: the two are timed seconds apart.

`convergence`: the variants of the shipped scenarios at 4, 2, 1 and 0.5 ms against the
monolithic reference (harness.engines.reference), with the legacy drives: the relative error of
each drive energy, which must shrink with the step.

`ecco`: the coupling's own energy error (docs/results.md#power-bonds) against the steps
taken, for franchetti2021's self_regulating and demian2022's compensated variants run as
systems of FMUs in libcosim: at the fixed steps of `convergence` and under ECCO at
ECCO_TOLERANCES. Per run the steps, E_drawn and its relative error against the monolithic
reference (and E_in's, relative to E_drawn), the bonds' summed |W_bond_error| and the
largest event lag (a phase start to the
first communication point at or after it); `ecco.png` plots both errors against the steps
(log-log).

`sweep`: runs per second of a parameter sweep with 1 and 2 Dask worker processes.

`study`: a study's runs per CPU-second in one process and where their time goes (the
closed-loop step, the start-up a run without a reused FMU instance would add), and its runs
per second on local Dask clusters of 1, 2 and 4 workers reached by their scheduler's
address, per worker (`harness.bench.studies.study_benchmark`).

`study_step`: the error the study's communication step leaves in E_drawn, over the first
tasks of each committed study at 4, 2, 1 and 0.5 ms, relative to 0.5 ms; checked at each task
model's step (`harness.bench.targets.STUDY_STEP_BOUND`).

`cli_help`: wall time of `python -m harness --help` in a fresh interpreter, best of repeats.

Checks (CHECKS): after the tables, the figures that must hold on any machine, each with its
bound and whether it holds, printed and written to checks.csv (the rows of benchmarks not run
this time re-evaluated from their CSVs in the folder): every mechanism's step dearer than the
stock floor's (its physics on top of the same FMI calls) and the top-level help under a
second. `bench` exits 1 when a
check of the benchmarks it ran fails, after writing every table.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from harness.errors import UserError

if TYPE_CHECKING:  # the command's help imports none of what the benchmarks need
    import pandas as pd

BENCH_DIR = Path(__file__).resolve().parents[2] / "results" / "bench"
# master_share's run and replay are timed seconds apart, so each needs enough repeats for its
# best to reach the machine's quiet state (with 3, one bench run in three measured a variant's
# FMU calls 6.7 % above its whole step)
MASTER_SHARE_REPEATS = 5


@dataclass(frozen=True)
class Benchmark:
    """A benchmark: the function `harness.bench.<module>.<function>`, imported when it runs,
    called with the steps and repeats it takes (steps: FMU steps per repeat; repeats: at
    least min_repeats)."""

    module: str
    function: str
    steps: bool = True
    repeats: bool = True
    min_repeats: int = 1

    def __call__(self, steps: int, repeats: int) -> pd.DataFrame:
        function = getattr(importlib.import_module(f"harness.bench.{self.module}"),
                           self.function)
        given = {"steps": steps} if self.steps else {}
        if self.repeats:
            given["repeats"] = max(repeats, self.min_repeats)
        return function(**given)


BENCHMARKS: dict[str, Callable[..., pd.DataFrame]] = {
    "fmu_step": Benchmark("steps", "fmu_step"),
    "native_step": Benchmark("steps", "native_step"),
    # steps and repeats apply to the FMU-only step cost
    "cosim": Benchmark("steps", "cosim"),
    # steps do not apply; at least MASTER_SHARE_REPEATS repeats
    "master_share": Benchmark("steps", "master_share", min_repeats=MASTER_SHARE_REPEATS),
    "convergence": Benchmark("studies", "convergence", steps=False, repeats=False),
    "ecco": Benchmark("studies", "ecco"),
    # runs/s of a parameter sweep with 1 and 2 worker processes
    "sweep": Benchmark("studies", "sweep_benchmark", steps=False, repeats=False),
    "study": Benchmark("studies", "study_benchmark"),
    "study_step": Benchmark("studies", "study_step"),
    "cli_help": Benchmark("studies", "cli_help"),
}
# the figure a benchmark's table gets beside its CSV: (module, function)
PLOTS = {"ecco": ("studies", "ecco_plot")}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--step-count", dest="steps", type=int, default=20_000, metavar="N",
                        help="FMU steps per repeat")
    parser.add_argument("--repeats", type=int, default=3, help="repeats; the best counts")
    parser.add_argument("--out", type=Path, default=BENCH_DIR, help="output folder")
    parser.add_argument("--only", default="all",
                        help=f"comma-separated benchmarks from {', '.join(BENCHMARKS)} "
                             "(default all)")


def run(args: argparse.Namespace) -> int:
    if args.steps < 1 or args.repeats < 1:
        raise UserError("--step-count and --repeats must be at least 1")
    names = list(BENCHMARKS) if args.only == "all" else [n.strip() for n in args.only.split(",")]
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        raise UserError(f"--only: unknown benchmark(s) {unknown}; choose from {list(BENCHMARKS)}")
    from harness.bench.targets import checks, earlier_tables
    from harness.io import write_csv

    tables = {}
    for name in names:
        tables[name] = BENCHMARKS[name](steps=args.steps, repeats=args.repeats)
        print(write_csv(tables[name], args.out / f"{name}.csv"))
        if name in PLOTS:
            module, function = PLOTS[name]
            plot = getattr(importlib.import_module(f"harness.bench.{module}"), function)
            print(plot(tables[name], args.out / f"{name}.png"))
        print(tables[name].to_string(index=False))
    checked = checks(tables)
    if checked.empty:
        return 0
    earlier = earlier_tables(args.out, names)
    print(write_csv(checks({**earlier, **tables}), args.out / "checks.csv"))
    print(checked.to_string(index=False))
    for check in checked[~checked.passed].itertuples():
        figure = f"{check.figure} = {check.value:.4g} {check.unit}".rstrip()
        print(f"bench check failed: {check.benchmark}: {figure}, must be {check.relation} "
              f"{check.bound:.4g}", file=sys.stderr)
    return 0 if checked.passed.all() else 1
