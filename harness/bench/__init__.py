"""Benchmarks: `python -m harness bench` writes one CSV per benchmark to results/bench/.

Each benchmark is a function (steps, repeats) -> table; BENCHMARKS maps the CSV name to it.

`fmu_step`: the cost of one communication step of SelfRegulatingBalancer stepped by FMPy,
with the calls the co-simulation master makes per step (harness.run.master: setReal tau_drive,
doStep, getReal theta and omega), next to the same loop over `BenchFloor`, a pythonfmu
FMU that only copies its input to its output, with pythonfmu's own binary: the floor that
pythonfmu imposes on any FMU made with it. `BenchFloorRuntime` is the same slave on our
runtime (harness/fmu/runtime), as every FMU of the product is.

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
and that of its FMU calls alone (the run's efforts and input changes replayed through the
master's prepared calls, the recording read included), best of repeats each, and their
difference, the master's share: its set-up and result assembly spread over the steps, the
controller and motor, the loop.

`convergence`: the franchetti2021 variants at 4, 2, 1 and 0.5 ms against the monolithic
reference (harness.run.reference): the relative error of each drive energy, which must shrink
with the step.

`ecco`: the coupling's own energy error (docs/results.md#power-bonds) against the steps
taken, for franchetti2021's self_regulating and demian2022's compensated variants run as
systems of FMUs in libcosim: at the fixed steps of `convergence` and under ECCO at
ECCO_TOLERANCES. Per run the steps, E_drawn and its relative error against the monolithic
reference (and E_in's, relative to E_drawn), the bonds' summed |W_bond_error| and the
largest event lag (a phase start to the
first communication point at or after it); `ecco.png` plots both errors against the steps
(log-log).

`sweep`: runs per second of a parameter sweep with 1 and 2 Dask worker processes.

`cli_help`: wall time of `python -m harness --help` in a fresh interpreter, best of repeats.

Checks (CHECKS): after the tables, the figures that must hold on any machine, each with its
bound and whether it holds, printed and written to checks.csv (the rows of benchmarks not run
this time re-evaluated from their CSVs in the folder): every mechanism's step dearer than the
stock floor's (its physics on top of the same FMI calls), a run's FMU calls alone cheaper than
its whole closed-loop step, and the top-level help under a second. `bench` exits 1 when a
check of the benchmarks it ran fails, after writing every table.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from fmpy import read_model_description
from fmpy.fmi2 import fmi2True

from fmu_src.mechanism import Port
from harness import registry
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU
from harness.io import write_csv
from harness.run import master, reference
from harness.run import scenario_files as scenarios
from harness.run.results import RESULTS_DIR
from harness.sweeps import definition as sweep_definition
from harness.sweeps import execution as sweep_execution

BENCH_DIR = RESULTS_DIR / "bench"
FLOOR_SOURCE_DIR = Path(__file__).resolve().parent / "floor"
FLOOR_BUILD_DIR = fmu_build.DEFAULT_DEST.parent / "bench"
STEP_SIZE = 1e-3  # communication step [s], the harness default
NATIVE_HOST_SOURCE = fmu_build.HOST_SOURCE
NATIVE_HOST_BUILD = fmu_build.DEFAULT_DEST.parent / "native_host" / "fmi2_host"


@dataclass(frozen=True)
class StepLoop:
    """A timed FMU and what the master sets and reads at every step (as harness.run.master)."""

    fmu_path: Callable[[], Path]  # the built FMU (the floors are built here, the others located)
    input: str
    outputs: tuple[str, ...]


def mechanism_loop(model: str, joints: tuple[Port, ...]) -> StepLoop:
    """The master's step loop of a mechanism: its first joint's effort set (the others stay
    at their start values), every joint's position and speed read."""
    return StepLoop(lambda: fmu_build.locate(model), joints[0].effort,
                    tuple(name for joint in joints for name in (joint.position, joint.flow)))


# the mechanism FMUs (harness.registry), and the floor: the trivial slave on pythonfmu's own
# binary (the stock floor every ratio is taken to) and on our runtime
MECHANISM_LOOPS = {model: mechanism_loop(model, r.joints())
                   for model, r in registry.mechanisms().items()}
FLOOR = "BenchFloor"
FLOOR_RUNTIME = "BenchFloorRuntime"
FLOOR_MODELS = (FLOOR, FLOOR_RUNTIME)
STEP_LOOPS = {
    FLOOR: StepLoop(lambda: fmu_build.fmu_path(FLOOR, FLOOR_BUILD_DIR / "stock",
                                               FLOOR_SOURCE_DIR, runtime=False), "u", ("y",)),
    FLOOR_RUNTIME: StepLoop(
        lambda: fmu_build.fmu_path(FLOOR, FLOOR_BUILD_DIR, FLOOR_SOURCE_DIR), "u", ("y",)),
    **MECHANISM_LOOPS,
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
    floor = best[FLOOR]
    return pd.DataFrame({
        "model": list(best),
        "step_size": STEP_SIZE,
        "steps": steps,
        "repeats": repeats,
        "us_per_step": [1e6 * cost for cost in best.values()],
        "ratio_to_floor": [cost / floor for cost in best.values()],
    })


def native_host() -> Path:
    """The C host of tests/native_host, compiled when its inputs change."""
    return fmu_build.compiled(NATIVE_HOST_SOURCE, NATIVE_HOST_BUILD)


def stock_environment() -> dict[str, str]:
    """What a host that is not a Python process needs for pythonfmu's own binary: the
    building interpreter's libpython preloaded and its prefix as PYTHONHOME."""
    library = fmu_build.libpython()
    if library is None:
        raise UserError("the stock floor needs a shared-library CPython (libpython) to run in "
                        "the C host")
    return {"LD_PRELOAD": str(library), "PYTHONHOME": sys.base_prefix}


def native_seconds_per_step(host: Path, fmu: Path, loop: StepLoop, steps: int,
                            environment: dict[str, str] | None = None) -> float:
    """Mean CPU time of one step [s] of the C host's loop over an unzipped copy of the FMU,
    from t = 0, in the given environment (default: an empty one)."""
    md = read_model_description(fmu)
    refs = {v.name: v.valueReference for v in md.modelVariables}
    with tempfile.TemporaryDirectory(prefix="native_") as folder:
        zipfile.ZipFile(fmu).extractall(folder)
        done = subprocess.run(
            [str(host), "-b", str(refs[loop.input]), folder, md.coSimulation.modelIdentifier,
             md.guid, str(steps * STEP_SIZE), str(STEP_SIZE),
             *(str(refs[n]) for n in loop.outputs)],
            env=environment or {}, capture_output=True, text=True, check=True)
    return float(re.search(r"^cpu_seconds_per_step (\S+)$", done.stderr, re.MULTILINE).group(1))


def native_step(steps: int = 20_000, repeats: int = 3) -> pd.DataFrame:
    """Best-of-repeats cost of one 1 ms step of the floors and of each mechanism FMU [us]: in
    the C host, in FMPy, and their ratio, and the C host's cost over the stock floor's in the C
    host. Both start from the initialised FMU at t = 0, so they run the same trajectory."""
    host = native_host()
    rows = []
    for model, loop in STEP_LOOPS.items():
        environment = stock_environment() if model == FLOOR else None
        native, python = float("inf"), float("inf")
        for _ in range(repeats):
            native = min(native, native_seconds_per_step(host, loop.fmu_path(), loop, steps,
                                                         environment))
            with CoSimFMU(loop.fmu_path(), instance_name=f"bench.{model}") as fmu:
                fmu.initialize()
                python = min(python, seconds_per_step(fmu, loop, steps))
        rows.append({"model": model, "step_size": STEP_SIZE, "steps": steps,
                     "repeats": repeats, "us_per_step_c_host": 1e6 * native,
                     "us_per_step_fmpy": 1e6 * python, "ratio_c_host_to_fmpy": native / python})
    table = pd.DataFrame(rows)
    table["ratio_c_host_to_floor"] = (table.us_per_step_c_host
                                      / table.us_per_step_c_host[table.model == FLOOR].iloc[0])
    return table


def cosim(steps: int = 20_000, repeats: int = 3) -> pd.DataFrame:
    """Wall time, real-time factor and CPU time per closed-loop step of each variant of each
    shipped scenario at 1 ms, the latter against the BenchFloor step.

    Each run is timed as `make cosim` runs it (FMU instantiation included); FMU-only time is
    the run's step count times the model's best fmu_step cost where that was measured.
    """
    step_cost = (fmu_step(steps, repeats).set_index("model").us_per_step * 1e-6).to_dict()
    floor = step_cost[FLOOR]
    rows = []
    for name in scenarios.available():
        scenario = scenarios.load(name)
        for variant in scenario.variants.values():
            start, cpu_start = time.perf_counter(), time.thread_time()
            run = master.run(scenario, variant, STEP_SIZE)
            wall, cpu = time.perf_counter() - start, time.thread_time() - cpu_start
            n_steps = round(scenario.duration / STEP_SIZE)
            rows.append({"scenario": name, "variant": variant.name, "model": run.model,
                         "simulated_s": scenario.duration, "steps": n_steps, "wall_s": wall,
                         "real_time_factor": scenario.duration / wall,
                         "fmu_only_s": n_steps * step_cost.get(run.model, float("nan")),
                         "cpu_s": cpu, "us_per_step": 1e6 * cpu / n_steps,
                         "ratio_to_floor": cpu / n_steps / floor})
    table = pd.DataFrame(rows)
    total = {"scenario": "all", "variant": "all", "model": "",
             **table[["simulated_s", "steps", "wall_s", "cpu_s"]].sum().to_dict()}
    total["real_time_factor"] = total["simulated_s"] / total["wall_s"]
    total["fmu_only_s"] = float("nan")
    total["us_per_step"] = 1e6 * total["cpu_s"] / total["steps"]
    total["ratio_to_floor"] = total["cpu_s"] / total["steps"] / floor
    return pd.concat([table, pd.DataFrame([total])], ignore_index=True)


def replay_seconds(scenario: scenarios.Scenario, variant: scenarios.Variant,
                   run: master.RunResult) -> float:
    """CPU time [s] of this thread in the FMU calls alone of a run made with keep_traces: its
    efforts and input changes replayed through the master's own prepared calls
    (`master.FMICalls`: setReal of the efforts, the input changes, doStep, getReal of the
    joints' states, and the recording read every RECORD_INTERVAL), with no controller and no
    motor (the replay's own loop, copying each step's efforts into the C array, counts here);
    the FMU instantiated and initialised as in the run, untimed. RuntimeError if the replay
    does not end where the run ended."""
    scenario = scenario.for_variant(variant)
    joints, step_size = scenario.joints, run.step_size
    n_steps = round(scenario.duration / step_size)
    times = np.arange(n_steps + 1) * step_size
    inputs = scenario.inputs(times, variant)
    record_every = max(1, round(master.RECORD_INTERVAL / step_size))
    efforts = [trace.effort.tolist() for trace in run.traces]
    with CoSimFMU(fmu_build.locate(run.model), f"replay.{scenario.name}") as fmu:
        fmu.set({name: signal[0] for name, signal in inputs.items()})
        fmu.initialize(run.parameters, stop_time=scenario.duration)
        calls = master.FMICalls(fmu, [joint.effort for joint in joints],
                                [name for joint in joints for name in (joint.position,
                                                                      joint.speed)],
                                fmu.names("output") + list(inputs), len(fmu.messages))
        changes = master.input_changes(fmu, inputs)
        values, step_times = calls.inputs, times.tolist()
        start = time.thread_time()
        calls.record()
        for first in range(0, n_steps, record_every):
            last = min(first + record_every, n_steps)
            for k in range(first, last):
                for j, effort in enumerate(efforts):
                    values[j] = effort[k]
                calls.set_inputs()
                if k in changes:
                    for set_input, value_array, value, _ in changes[k]:
                        value_array[0] = value
                        set_input()
                calls.do_step(step_times[k], step_size, fmi2True)
                calls.get_states()
            if last - first == record_every:
                calls.record()
        seconds = time.thread_time() - start
        end = [value for trace in run.traces for value in (trace.position[-1], trace.speed[-1])]
        if calls.states[:] != end:
            raise RuntimeError(f"{scenario.name}.{variant.name}: the replay ends at "
                               f"{calls.states[:]}, the run at {end}")
        return seconds


def master_share(steps: int = 0, repeats: int = 3,
                 scenario_name: str = "franchetti2021") -> pd.DataFrame:
    """The master's share of a closed-loop step at 1 ms per variant: the CPU time of one step
    of the run (as `cosim`: set-up, controller, motor, FMU calls, recording, result assembly;
    `us_per_step`) less that of its FMU calls alone (`replay_seconds`; `fmu_calls_us_per_step`),
    best of repeats each."""
    scenario = scenarios.load(scenario_name)
    rows = []
    for variant in scenario.variants.values():
        run_cost = fmu_cost = float("inf")
        for _ in range(repeats):
            start = time.thread_time()
            run = master.run(scenario, variant, STEP_SIZE, keep_traces=True)
            run_cost = min(run_cost, time.thread_time() - start)
            fmu_cost = min(fmu_cost, replay_seconds(scenario, variant, run))
        n_steps = round(scenario.duration / STEP_SIZE)
        rows.append({"scenario": scenario_name, "variant": variant.name, "model": run.model,
                     "steps": n_steps, "us_per_step": 1e6 * run_cost / n_steps,
                     "fmu_calls_us_per_step": 1e6 * fmu_cost / n_steps,
                     "master_us_per_step": 1e6 * (run_cost - fmu_cost) / n_steps})
    return pd.DataFrame(rows)


CONVERGENCE_STEPS = (4e-3, 2e-3, 1e-3, 0.5e-3)  # communication steps [s]


def convergence(steps: int = 0, repeats: int = 0,
                scenario_name: str = "franchetti2021") -> pd.DataFrame:
    """Relative error of each drive energy against the monolithic reference, per step size,
    for the variants whose model has one.

    The error is |E - E_ref| / max(|E_ref|, E_drawn_ref): relative to the metric, or to the
    run's drawn energy when the metric is a small difference (as in the tests).
    """
    scenario = scenarios.load(scenario_name)
    rows = []
    for variant in scenario.variants.values():
        if (variant.model or scenario.model) not in reference.PHYSICS:
            continue  # no monolithic reference (active_relocation's self-locking screw)
        ref = reference.simulate(scenario, variant).metrics
        scale = {name: max(abs(value), ref["E_drawn"]) for name, value in ref.items()}
        for step in CONVERGENCE_STEPS:
            run = master.run(scenario, variant, step)
            errors = {f"err_{name}": abs(run.metrics[name] - ref[name]) / scale[name]
                      for name in reference.ENERGIES}
            rows.append({"scenario": scenario_name, "variant": variant.name, "step_size": step,
                         **errors, "max_rel_err": max(errors.values())})
    return pd.DataFrame(rows)


ECCO_CASES = (("franchetti2021", "self_regulating"), ("demian2022", "compensated"))
# ECCO's absolute tolerances on a bond's energy residual per step [J], loose to tight
ECCO_TOLERANCES = (1e-5, 1e-6, 1e-7)


def ecco(steps: int = 0, repeats: int = 0,
         cases: Sequence[tuple[str, str]] = ECCO_CASES,
         step_sizes: Sequence[float] = CONVERGENCE_STEPS,
         tolerances: Sequence[float] = ECCO_TOLERANCES) -> pd.DataFrame:
    """E_drawn's relative error against the monolithic reference and the coupling's energy
    error against the number of steps, per case: libcosim at each fixed step, then ECCO at
    each tolerance (its first step 1 ms, the other settings their defaults)."""
    from harness.systems import description, engines, writers

    rows = []
    for scenario_name, variant_name in cases:
        scenario = scenarios.load(scenario_name)
        variant = scenario.variant(variant_name)
        ref = reference.simulate(scenario, variant).metrics
        drawn = ref["E_drawn"]
        runs = [("fixed", h, None, description.describe(scenario, variant, h))
                for h in step_sizes]
        runs += [("ecco", master.DEFAULT_STEP, tolerance, description.describe(
            scenario, variant, master.DEFAULT_STEP,
            ecco=description.EccoSettings(abs_tolerance=tolerance))) for tolerance in tolerances]
        with tempfile.TemporaryDirectory() as folder:
            for algorithm, h, tolerance, described in runs:
                run = engines.run_libcosim(described, None if tolerance is not None
                                          else writers.write_osp(described, Path(folder)))
                bond_errors = [value for name, value in run.metrics.items()
                               if name.startswith("W_bond_error")]
                rows.append({
                    "scenario": scenario_name, "variant": variant_name,
                    "algorithm": algorithm, "step_size": run.step_size,
                    "abs_tolerance": tolerance,
                    "steps": run.metrics.get("steps", round(scenario.duration / h)),
                    "E_drawn": run.metrics["E_drawn"], "E_drawn_ref": drawn,
                    "err_E_drawn": abs(run.metrics["E_drawn"] - drawn) / drawn,
                    # E_in has no rectification: relative to E_drawn, as in convergence
                    "err_E_in": abs(run.metrics["E_in"] - ref["E_in"]) / drawn,
                    "bond_error": sum(abs(e) for e in bond_errors),
                    "rel_bond_error": sum(abs(e) for e in bond_errors) / drawn,
                    "event_lag_max": run.metrics.get("event_lag_max", 0.0)})
    return pd.DataFrame(rows)


def ecco_plot(table: pd.DataFrame, path: Path) -> Path:
    """ecco.png: per case, E_drawn's relative error and the coupling's relative energy error
    (|W_bond_error| / E_drawn_ref) against the steps taken, fixed step and ECCO (log-log)."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    from harness.io import save_figure

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for (case, rows), colour in zip(table.groupby(["scenario", "variant"], sort=False),
                                    ("C0", "C1", "C2", "C3"), strict=False):
        for algorithm, marker in (("fixed", "o-"), ("ecco", "s--")):
            chosen = rows[rows.algorithm == algorithm]
            for ax, column in zip(axes, ("err_E_drawn", "rel_bond_error"), strict=True):
                ax.loglog(chosen.steps, chosen[column], marker, color=colour,
                          label=f"{'/'.join(case)} {algorithm}")
    for ax, title in zip(axes, ("E_drawn: relative error against the monolithic reference",
                                "coupling: |W_bond_error| / E_drawn"), strict=True):
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("communication steps")
        ax.xaxis.set_minor_formatter(NullFormatter())  # decades only: minor labels overlap
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path)


BENCH_SWEEP = """
name = "bench"
scenario = "franchetti2021"
variants = ["self_regulating"]
[[axes]]
name = "payload"
set = ['phases["III regulate"].inputs.payload',
       'phases["III regulate"].inputs.counterweight_added']
range = {{ start = 0.0, stop = 8.0, num = {runs} }}
"""


def sweep_benchmark(runs: int = 12, workers: Sequence[int] = (1, 2)) -> pd.DataFrame:
    """Runs per second of a franchetti2021 payload sweep (35 s task at 1 ms) with each number
    of worker processes, one run per task, results stored as in a sweep. Start-up (cluster,
    imports, one FMU instance per worker) is not timed. speed_up is against the first row."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="sweep_bench_") as tmp:
        path = Path(tmp) / "bench.toml"
        path.write_text(BENCH_SWEEP.format(runs=runs))
        sweep = sweep_definition.load(path)
        fmu_build.locate(sweep.scenario.model)
        for n in workers:
            out = Path(tmp) / f"workers_{n}"
            client = sweep_execution.local_client(n)
            try:
                client.run(sweep_execution.warm_up, sweep.scenario.model)
                start = time.perf_counter()
                done, failed = sweep_execution.execute(sweep, sweep_definition.plan(sweep), out,
                                                       client, 1, quiet=True)
                seconds = time.perf_counter() - start
            finally:
                sweep_execution.close_client(client)
            if failed:
                raise RuntimeError(f"{failed} of {done} benchmark runs failed")
            rows.append({"workers": n, "runs": done, "seconds": seconds,
                        "runs_per_s": done / seconds})
    table = pd.DataFrame(rows)
    table["speed_up"] = table.runs_per_s / table.runs_per_s.iloc[0]
    return table


HELP_COMMAND = ("-m", "harness", "--help")
HELP_SECONDS_BOUND = 1.0  # wall time of the top-level help [s]
CHECKOUT = Path(__file__).resolve().parents[2]  # where `-m harness` finds this harness


def cli_help(steps: int = 0, repeats: int = 3) -> pd.DataFrame:
    """Wall time [s] of `python -m harness --help` in a fresh interpreter (start-up and the
    CLI's imports), best and worst of repeats."""
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, *HELP_COMMAND], cwd=CHECKOUT, capture_output=True,
                       check=True)
        seconds.append(time.perf_counter() - start)
    return pd.DataFrame({"command": ["python " + " ".join(HELP_COMMAND)], "repeats": repeats,
                         "best_s": min(seconds), "worst_s": max(seconds)})


@dataclass(frozen=True)
class Check:
    """A benchmark figure that must lie on one side of a bound (a NaN figure fails)."""

    benchmark: str
    figure: str
    value: float
    relation: str  # "<" or ">": value relation bound must hold
    bound: float
    unit: str

    @property
    def passed(self) -> bool:
        return self.value < self.bound if self.relation == "<" else self.value > self.bound


def fmu_step_checks(table: pd.DataFrame) -> Iterator[Check]:
    """Every mechanism's step costs more than the stock floor's: ratio_to_floor > 1."""
    for row in table[~table.model.isin(FLOOR_MODELS)].itertuples():
        yield Check("fmu_step", f"{row.model} ratio_to_floor", row.ratio_to_floor, ">", 1.0, "")


def master_share_checks(table: pd.DataFrame) -> Iterator[Check]:
    """Per variant, its FMU calls alone cost less than its whole closed-loop step [us]."""
    for row in table.itertuples():
        yield Check("master_share", f"{row.scenario}.{row.variant} fmu_calls_us_per_step",
                    row.fmu_calls_us_per_step, "<", row.us_per_step, "us")


def cli_help_checks(table: pd.DataFrame) -> Iterator[Check]:
    """The top-level help, best of repeats, takes under HELP_SECONDS_BOUND."""
    for row in table.itertuples():
        yield Check("cli_help", f"{row.command} best_s", row.best_s, "<", HELP_SECONDS_BOUND,
                    "s")


CHECKS: dict[str, Callable[[pd.DataFrame], Iterator[Check]]] = {
    "fmu_step": fmu_step_checks,
    "master_share": master_share_checks,
    "cli_help": cli_help_checks,
}


def checks(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """The checks of the given benchmark tables (name -> table), in CHECKS' order: benchmark,
    figure, value, relation, bound, unit, passed."""
    rows = [{**vars(check), "passed": check.passed}
            for name, check_table in CHECKS.items() if name in tables
            for check in check_table(tables[name])]
    return pd.DataFrame(rows, columns=["benchmark", "figure", "value", "relation", "bound",
                                       "unit", "passed"])


def earlier_tables(folder: Path, skip: Sequence[str]) -> dict[str, pd.DataFrame]:
    """The checked benchmarks' tables already in folder, but those in skip; UserError naming
    a file that is not such a table."""
    tables = {}
    for name in CHECKS:
        path = folder / f"{name}.csv"
        if name in skip or not path.is_file():
            continue
        try:
            tables[name] = pd.read_csv(path)
            checks({name: tables[name]})
        except (OSError, UnicodeDecodeError, ValueError, AttributeError, KeyError) as error:
            raise UserError(f"{path}: not a {name} table ({error}); rerun --only {name} or "
                            "remove it") from None
    return tables


BENCHMARKS: dict[str, Callable[..., pd.DataFrame]] = {
    "fmu_step": fmu_step,
    "native_step": native_step,
    # steps and repeats apply to the FMU-only step cost
    "cosim": cosim,
    # steps do not apply
    "master_share": master_share,
    # steps and repeats do not apply
    "convergence": lambda steps, repeats: convergence(),
    "ecco": ecco,
    # runs/s of a parameter sweep with 1 and 2 worker processes; steps and repeats do not apply
    "sweep": lambda steps, repeats: sweep_benchmark(),
    # steps do not apply
    "cli_help": cli_help,
}


PLOTS: dict[str, Callable[[pd.DataFrame, Path], Path]] = {"ecco": ecco_plot}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--step-count", dest="steps", type=int, default=20_000, metavar="N",
                        help="FMU steps per repeat")
    parser.add_argument("--steps", dest="steps", type=int, default=argparse.SUPPRESS,
                        help=argparse.SUPPRESS)  # former spelling
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
    tables = {}
    for name in names:
        tables[name] = BENCHMARKS[name](steps=args.steps, repeats=args.repeats)
        print(write_csv(tables[name], args.out / f"{name}.csv"))
        if name in PLOTS:
            print(PLOTS[name](tables[name], args.out / f"{name}.png"))
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
