"""The benchmark studies: step convergence against the monolithic reference, libcosim's
fixed step against ECCO, a sweep's scaling over workers, a study's throughput and step error,
and the CLI's help time."""

from __future__ import annotations

import logging
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd
from distributed import LocalCluster

from harness import scenarios, study
from harness.drive.metrics import ENERGIES
from harness.engines import DEFAULT_STEP, fmpy_master, reference
from harness.engines.plan import prepare
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU
from harness.run.sizing import pinned_drives, stored_pins
from harness.study import execution as study_execution
from harness.study import model as study_model
from harness.study import tasks as study_tasks
from harness.sweeps import connect
from harness.sweeps import definition as sweep_definition
from harness.sweeps import execution as sweep_execution

if TYPE_CHECKING:
    from matplotlib.figure import Figure

CONVERGENCE_STEPS = (4e-3, 2e-3, 1e-3, 0.5e-3)  # communication steps [s]
# the shipped scenarios (the headline tables), legacy drives
CONVERGENCE_SCENARIOS = ("franchetti2021", "ciupitu2018", "demian2022")


def convergence(steps: int = 0, repeats: int = 0,
                scenario_names: Sequence[str] = CONVERGENCE_SCENARIOS) -> pd.DataFrame:
    """Relative error of each drive energy (summed over a scenario's drives) against the
    monolithic reference, per scenario and step size, for the variants whose model has one.

    The error is |E - E_ref| / max(|E_ref|, E_drawn_ref): relative to the metric, or to the
    run's drawn energy when the metric is a small difference (as in the tests).
    """
    rows = []
    for scenario_name in scenario_names:
        scenario = scenarios.load(scenario_name)
        for variant in scenario.variants.values():
            if not reference.supports(variant.model or scenario.model):
                continue  # no monolithic reference (active_relocation's self-locking screw)
            ref = reference.run(prepare(scenario, variant, DEFAULT_STEP)).metrics
            scale = {name: max(abs(ref[name]), ref["E_drawn"]) for name in ENERGIES}
            for step in CONVERGENCE_STEPS:
                run = fmpy_master.run(prepare(scenario, variant, step))
                errors = {f"err_{name}": abs(run.metrics[name] - ref[name]) / scale[name]
                          for name in ENERGIES}
                rows.append({"scenario": scenario_name, "variant": variant.name,
                             "step_size": step, **errors, "max_rel_err": max(errors.values())})
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
    from harness.engines.libcosim import run as fixed_step
    from harness.engines.libcosim import run_ecco
    from harness.engines.settings import EccoSettings

    rows = []
    for scenario_name, variant_name in cases:
        scenario = scenarios.load(scenario_name)
        variant = scenario.variant(variant_name)
        ref = reference.run(prepare(scenario, variant, DEFAULT_STEP)).metrics
        drawn = ref["E_drawn"]
        runs = [("fixed", h, None, partial(fixed_step, prepare(scenario, variant, h)))
                for h in step_sizes]
        runs += [("ecco", DEFAULT_STEP, tolerance, partial(
            run_ecco, prepare(scenario, variant, DEFAULT_STEP),
            ecco=EccoSettings(abs_tolerance=tolerance))) for tolerance in tolerances]
        for algorithm, h, tolerance, make_run in runs:
            run = make_run()
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


def ecco_figure(table: pd.DataFrame) -> Figure:
    """Per case, E_drawn's relative error against the monolithic reference (left) and the
    coupling's relative energy error |W_bond_error| / E_drawn_ref (right) against the steps
    taken, fixed step (solid) and ECCO (dashed), log-log."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from harness.run.plots import fit_suptitle, readable_log

    fig = Figure(figsize=(11, 4.8), layout="constrained")
    axes = fig.subplots(1, 2)
    handles = []
    for (case, rows), colour in zip(table.groupby(["scenario", "variant"], sort=False),
                                    ("C0", "C1", "C2", "C3"), strict=False):
        for algorithm, style in (("fixed", "o-"), ("ecco", "s--")):
            chosen = rows[rows.algorithm == algorithm]
            for ax, column in zip(axes, ("err_E_drawn", "rel_bond_error"), strict=True):
                ax.loglog(chosen.steps, chosen[column], style, color=colour)
            handles.append(Line2D([], [], color=colour, marker=style[0], ls=style[1:],
                                  label=f"{'/'.join(case)}, {algorithm}"
                                        f"{' step' if algorithm == 'fixed' else ''}"))
    for ax, title, label in zip(
            axes, ("E_drawn against the monolithic reference",
                   "energy the coupling makes or loses"),
            ("relative error of E_drawn [-]", "|W_bond_error| / E_drawn_ref [-]"),
            strict=True):
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("communication steps over the task [-]")
        ax.set_ylabel(label)
        readable_log(ax.xaxis)
        readable_log(ax.yaxis)
        ax.grid(alpha=0.3, which="both")
    fig.legend(handles=handles, loc="outside lower center", ncols=2, fontsize=8)
    fit_suptitle(fig, "libcosim at a fixed step against ECCO: energy errors against the "
                      "steps taken")
    return fig


def ecco_plot(table: pd.DataFrame, path: Path) -> Path:
    """ecco.png: `ecco_figure`, written at path."""
    from harness.io import save_figure

    return save_figure(ecco_figure(table), path)


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


STUDY_BENCH_SCENARIO = "franchetti2021"
STUDY_BENCH_TASKS = 2           # the study's first tasks: 24 runs of every variant and loss set
STUDY_BENCH_WORKERS = (1, 2, 4)  # local Dask workers, reached through their scheduler's address
STUDY_STEPS = (4e-3, 2e-3, 1e-3, 0.5e-3)  # communication steps of study_step [s]


def _study_tasks(n: int) -> tuple[study_model.TaskModel, list[study_tasks.Task]]:
    """The study's first n tasks of STUDY_BENCH_SCENARIO with the committed study's drives
    (sized on them here when there is no committed study)."""
    task_model = study_model.load(STUDY_BENCH_SCENARIO)
    drawn = [study_tasks.draw(task_model, study.DEFAULT_SEED, i) for i in range(n)]
    path = study.STUDY_DIR / STUDY_BENCH_SCENARIO / "drives.csv"
    if path.exists():
        pins = stored_pins(path)
    else:
        pins = {v: {joint: sized["pin"] for joint, sized in
                    study_execution.size_variant(drawn, v, task_model.step).items()}
                for v in task_model.template.variants}
    return task_model, [study_tasks.pinned(task, pins) for task in drawn]


def study_benchmark(steps: int = 0, repeats: int = 0) -> pd.DataFrame:
    """Where a study's time goes, and its throughput. In this process, every run of the
    study's first STUDY_BENCH_TASKS tasks of STUDY_BENCH_SCENARIO (each variant, each loss
    set) at the study's step, one FMU instance per model reused as a study worker does: CPU
    time, runs and simulated seconds per CPU-second, CPU time per step (the run's set-up and
    result assembly spread over its steps), and the start-up a fresh instance (extracting
    and loading the FMU, instantiating it) would add to each run without reuse. Then the
    same runs as a study executes them on a local Dask cluster of each of STUDY_BENCH_WORKERS
    single-threaded worker processes, reached through its scheduler's address as
    `--scheduler` reaches one: wall time, runs per second and per worker per second (cluster
    start-up and the first instances not timed)."""
    task_model, drawn = _study_tasks(STUDY_BENCH_TASKS)
    variants = list(task_model.template.variants)
    loss_sets = [ls for ls, _ in drawn[0].loss_sets()]
    jobs = [(v, ls) for v in variants for ls in loss_sets]
    models = {task_model.template.variant(v).model or task_model.template.model
              for v in variants}
    for model in models:
        sweep_execution.warm_up(model)
    start_up = {}
    for model in models:
        start = time.process_time()
        CoSimFMU(fmu_build.locate(model), f"bench.{model}").close()
        start_up[model] = time.process_time() - start
    cpu = time.process_time()
    rows = [study_execution.run_one(task, v, ls, task_model.step) for task in drawn
            for v, ls in jobs]
    cpu = time.process_time() - cpu
    if any(row["status"] != "ok" for row in rows):
        raise RuntimeError(f"benchmark runs failed: {[r['error'] for r in rows if r['error']]}")
    simulated = sum(row["duration"] for row in rows)
    n_steps = sum(round(row["duration"] / task_model.step) for row in rows)
    runs = len(rows)
    table = [{"setting": "one process", "workers": 1, "runs": runs, "cpu_s": cpu,
              "wall_s": float("nan"), "runs_per_cpu_s": runs / cpu,
              "simulated_s_per_cpu_s": simulated / cpu, "us_per_step": cpu / n_steps * 1e6,
              "start_up_s": sum(start_up.values()) / len(start_up),
              "start_up_share": sum(start_up.values()) / len(start_up) / (cpu / runs)}]
    todo = {task.row["task"]: jobs for task in drawn}
    with tempfile.TemporaryDirectory(prefix="study_bench_") as tmp:
        for n in STUDY_BENCH_WORKERS:
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = connect(cluster.scheduler_address)
            try:
                for model in models:
                    client.run(sweep_execution.warm_up, model)
                start = time.perf_counter()
                done, failed = study_execution.execute(Path(tmp) / f"workers_{n}", drawn, todo,
                                                       task_model.step, client, quiet=True)
                seconds = time.perf_counter() - start
            finally:
                client.close()
                cluster.close()
            if failed:
                raise RuntimeError(f"{failed} of {done} benchmark runs failed")
            table.append({"setting": "local Dask cluster", "workers": n, "runs": done,
                          "cpu_s": float("nan"), "wall_s": seconds,
                          "runs_per_s": done / seconds,
                          "runs_per_s_per_worker": done / seconds / n})
    return pd.DataFrame(table)


def study_step(steps: int = 0, repeats: int = 0) -> pd.DataFrame:
    """The study's error from its communication step: E_drawn of every variant in both loss
    sets over the first STUDY_BENCH_TASKS tasks of each task model with the study's drives,
    at each of STUDY_STEPS, relative to the finest (the master's error is first order in the
    step, so this is about the error at each step)."""
    rows = []
    for name in study_model.available():
        task_model = study_model.load(name)
        drawn = [study_tasks.draw(task_model, study.DEFAULT_SEED, i)
                 for i in range(STUDY_BENCH_TASKS)]
        path = study.STUDY_DIR / name / "drives.csv"
        if not path.exists():
            continue   # no committed study: no drives to run it with
        pins = stored_pins(path)
        for task in (study_tasks.pinned(t, pins) for t in drawn):
            for loss_set, scenario in task.loss_sets():
                for variant in scenario.variants:
                    chosen = scenario.variant(variant)
                    drives = pinned_drives(scenario.for_variant(chosen), loss_set,
                                           f"{task.name} variant {variant}")
                    drawn_energy = {}
                    for step in STUDY_STEPS:
                        try:
                            drawn_energy[step] = fmpy_master.run(prepare(
                                scenario, chosen, step, drives)).metrics["E_drawn"]
                        except UserError:   # an FMU refuses too long a step
                            drawn_energy[step] = float("nan")
                    finest = drawn_energy[STUDY_STEPS[-1]]
                    rows += [{"scenario": name, "task": task.row["task"], "variant": variant,
                              "losses": loss_set, "step_size": step, "E_drawn": value,
                              "rel_error": abs(value - finest) / abs(finest)}
                             for step, value in drawn_energy.items()]
    return pd.DataFrame(rows)
