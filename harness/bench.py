"""Benchmarks: `python -m harness bench` writes one CSV per benchmark to results/bench/.

Each benchmark is a function (steps, repeats) -> table; BENCHMARKS maps the CSV name to it,
so more (co-simulation real-time factor, parameter sweeps) are added as further functions.

`fmu_step`: the cost of one communication step of SelfRegulatingBalancer stepped by FMPy,
with the calls the co-simulation master makes per step (harness.master: setReal tau_drive,
doStep, getReal theta and omega), next to the same loop over `BenchFloor`, a pythonfmu
FMU that only copies its input to its output: the floor that FMI and the embedded
interpreter impose on any pythonfmu FMU.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness import fmu_build
from harness.fmi import CoSimFMU
from harness.results import RESULTS_DIR, write_csv
from harness.sweep import sweep_benchmark

BENCH_DIR = RESULTS_DIR / "bench"
FLOOR_SOURCE_DIR = Path(__file__).resolve().parent / "bench_fmus"
FLOOR_BUILD_DIR = fmu_build.DEFAULT_DEST.parent / "bench"
STEP_SIZE = 1e-3  # communication step [s], the harness default


@dataclass(frozen=True)
class StepLoop:
    """A timed FMU and what the master sets and reads at every step (as harness.master)."""

    fmu_path: Callable[[], Path]  # builds the FMU if it is stale
    input: str
    outputs: tuple[str, ...]


STEP_LOOPS = {
    "BenchFloor": StepLoop(
        lambda: fmu_build.fmu_path("BenchFloor", FLOOR_BUILD_DIR, FLOOR_SOURCE_DIR),
        "u", ("y",)),
    "SelfRegulatingBalancer": StepLoop(
        lambda: fmu_build.fmu_path("SelfRegulatingBalancer"), "tau_drive", ("theta", "omega")),
}


def seconds_per_step(fmu: CoSimFMU, loop: StepLoop, steps: int,
                     start_time: float = 0.0) -> float:
    """Mean CPU time of one step [s]: setReal(input), doStep, getReal(outputs).

    CPU time of this process, not wall time: on a shared machine other processes would
    otherwise count (pythonfmu runs the slave in the calling thread).
    """
    slave = fmu.slave
    input_ref = fmu.references([loop.input])
    output_refs = fmu.references(loop.outputs)
    value = [0.0]
    t0 = time.process_time()
    for k in range(steps):
        slave.setReal(input_ref, value)
        slave.doStep(start_time + k * STEP_SIZE, STEP_SIZE)
        slave.getReal(output_refs)
    return (time.process_time() - t0) / steps


def fmu_step(steps: int = 20_000, repeats: int = 3) -> pd.DataFrame:
    """Best-of-repeats cost of one 1 ms step per model [us] and its ratio to BenchFloor.

    The models take turns within each repeat, so drifts of the machine's speed hit both.
    """
    fmus = {name: CoSimFMU(loop.fmu_path(), instance_name=f"bench.{name}")
            for name, loop in STEP_LOOPS.items()}
    try:
        best = dict.fromkeys(fmus, float("inf"))
        for fmu in fmus.values():
            fmu.initialize()
        for repeat in range(repeats):
            for name, fmu in fmus.items():
                cost = seconds_per_step(fmu, STEP_LOOPS[name], steps, repeat * steps * STEP_SIZE)
                best[name] = min(best[name], cost)
    finally:
        for fmu in fmus.values():
            fmu.close()
    floor = best["BenchFloor"]
    return pd.DataFrame({
        "model": list(best),
        "step_size": STEP_SIZE,
        "steps": steps,
        "repeats": repeats,
        "us_per_step": [1e6 * cost for cost in best.values()],
        "ratio_to_floor": [cost / floor for cost in best.values()],
    })


BENCHMARKS: dict[str, Callable[..., pd.DataFrame]] = {
    "fmu_step": fmu_step,
    # runs/s of a parameter sweep with 1 and 2 worker processes; steps and repeats do not apply
    "sweep": lambda steps, repeats: sweep_benchmark(),
}

COMMAND = "bench"
HELP = "time one FMU communication step against a trivial pythonfmu FMU (results/bench)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--steps", type=int, default=20_000, help="steps per repeat")
    parser.add_argument("--repeats", type=int, default=3, help="repeats; the best counts")
    parser.add_argument("--out", type=Path, default=BENCH_DIR, help="output folder")
    parser.add_argument("--only", default="all",
                        help=f"comma-separated benchmarks from {', '.join(BENCHMARKS)} (default all)")


def run(args: argparse.Namespace) -> int:
    if args.steps < 1 or args.repeats < 1:
        raise ValueError("--steps and --repeats must be at least 1")
    names = list(BENCHMARKS) if args.only == "all" else [n.strip() for n in args.only.split(",")]
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        raise ValueError(f"--only: unknown benchmark(s) {unknown}; choose from {list(BENCHMARKS)}")
    for name in names:
        table = BENCHMARKS[name](steps=args.steps, repeats=args.repeats)
        print(write_csv(table, args.out / f"{name}.csv"))
        print(table.to_string(index=False))
    return 0
