"""`python -m harness cosim`: run scenarios and variants, write results/<scenario>/.

The runs (every selected variant of every selected scenario) are independent: with
`--workers N` above 1 they run in N worker processes (pythonfmu embeds one interpreter per
process, so processes, not threads), longest first, and each scenario's files are written
(by a worker as well: its plots cost as much as a run) as soon as its last run is done. A
run's numbers do not depend on the process it ran in.

Ctrl-C (`harness.interrupts`): the runs stop at their next recorded step (a worker process
never sees the SIGINT; its parent tells it), a scenario being written is written in full,
and the command exits with 130: what was written is complete, nothing else changed.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path

from tqdm import tqdm

from harness import interrupts
from harness.errors import UserError
from harness.run import losses, master, results
from harness.run import scenario_files as scenarios


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="all",
                        help="scenario name, TOML file, or 'all' (default: all shipped)")
    parser.add_argument("--variants", default="all",
                        help="'all' or a comma-separated list of variant names")
    parser.add_argument("--step", type=float, default=master.DEFAULT_STEP,
                        help="communication step [s] (default 1e-3)")
    parser.add_argument("--out", type=Path, default=results.RESULTS_DIR,
                        help="results folder; files go to OUT/<scenario>/ (default results/)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="worker processes running the variants in parallel (default: "
                             "the number of CPUs; 1 runs them one after another in this "
                             "process)")
    parser.add_argument("--losses", default="all",
                        help="'all' (default), 'ideal' or 'realistic': the scenario as written, "
                             "or with the losses of real parts (harness/losses/<scenario>.toml, "
                             "into OUT/<scenario>/realistic/; with all, a scenario without one "
                             "runs ideal only)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def selected_variants(scenario: scenarios.Scenario, spec: str) -> list[str]:
    """Variant names from 'all' or a comma-separated list; their eps baselines are always run."""
    names = list(scenario.variants) if spec == "all" else [v.strip() for v in spec.split(",")]
    for name in names:
        scenario.variant(name)  # UserError naming the choices (also for an empty name)
    baselines = [scenario.baselines[name] for name in names]
    return list(dict.fromkeys(names + baselines))


POLL_INTERVAL = 0.1  # [s] between the parent's looks at an interrupt while workers run


def run_variant(scenario: scenarios.Scenario, name: str, step: float,
                progress: Callable[[int], None] | None = None) -> master.RunResult:
    """One run (in a worker process, or here with a progress callback); KeyboardInterrupt
    at its next recorded step once an interrupt is requested."""
    def advance(steps: int) -> None:
        interrupts.stop_if_requested()
        if progress is not None:
            progress(steps)

    interrupts.stop_if_requested()
    return master.run(scenario, scenario.variant(name), step, progress=advance)


Plan = tuple[scenarios.Scenario, list[str]] | tuple[scenarios.Scenario, list[str], Path]


def run_all(plans: list[Plan], step: float, out: Path, workers: int = 1,
            quiet: bool = False) -> None:
    """Run every planned variant and write each scenario's result files (and print its
    summary) once its runs are done; with workers above 1 both in that many processes.
    A plan is (scenario, variants) or (scenario, variants, folder): its result set goes to
    the folder, by default OUT/<scenario>/.
    A SIGINT stops the runs (none is interrupted midway in its FMU, nor a write) and raises
    KeyboardInterrupt."""
    folders = [plan[2] if len(plan) > 2 else out / plan[0].name for plan in plans]
    jobs = [(index, scenario, name) for index, (scenario, names, *_) in enumerate(plans)
            for name in names]
    remaining = {index: len(names) for index, (_, names, *_) in enumerate(plans)}
    runs: dict[tuple[int, str], master.RunResult] = {}
    total = sum(round(scenario.duration / step) for _, scenario, _ in jobs)

    def finished(index: int, name: str, run: master.RunResult) -> tuple | None:
        """Book a run; the arguments of write_scenario when it was its scenario's last."""
        runs[index, name] = run
        remaining[index] -= 1
        if remaining[index]:
            return None
        scenario, names, *_ = plans[index]
        return scenario, [runs.pop((index, n)) for n in names], folders[index]

    with interrupts.deferred(), tqdm(total=total, unit="step", unit_scale=True,
                                     disable=quiet) as bar:
        if workers == 1 or len(jobs) == 1:
            for index, scenario, name in jobs:
                bar.set_postfix_str(f"{scenario.name}.{name}")
                write = finished(index, name, run_variant(scenario, name, step, bar.update))
                if write is not None:
                    tqdm.write(write_scenario(*write))
            return
        # longest runs first, so that the last ones to start are short; a scenario's files
        # are written by a worker too, while the others still run
        jobs.sort(key=lambda job: -job[1].duration)
        context = multiprocessing.get_context()
        stop = context.Event()  # the workers' interrupts.requested
        pool = ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=context,
                                   initializer=interrupts.ignore_in_worker, initargs=(stop,))

        def submit(*call: object) -> Future:
            with interrupts.blocked():  # the workers (started here) and the pool's threads
                return pool.submit(*call)

        try:
            pending = {submit(run_variant, scenario, name, step): (index, scenario, name)
                       for index, scenario, name in jobs}
            while pending:
                done, _ = wait(pending, POLL_INTERVAL, return_when=FIRST_COMPLETED)
                interrupts.stop_if_requested()
                for future in done:
                    job = pending.pop(future)
                    if job is None:  # a scenario's files written
                        tqdm.write(future.result())
                        continue
                    index, scenario, name = job
                    bar.update(round(scenario.duration / step))
                    bar.set_postfix_str(f"{scenario.name}.{name} done")
                    write = finished(index, name, future.result())
                    if write is not None:
                        pending[submit(write_scenario, *write)] = None
        finally:  # done, failed or interrupted: the runs still going stop at their next
            stop.set()  # recorded step, a scenario being written is finished
            pool.shutdown(cancel_futures=True)


def write_scenario(scenario: scenarios.Scenario, runs: list[master.RunResult],
                   folder: Path) -> str:
    """Write one scenario's result files into folder; their paths and its summary, to
    print."""
    paths = results.write_run(runs, scenario, folder)
    return "\n".join([*map(str, paths), results.summary_text(folder / "summary.csv", scenario)])


def run(args: argparse.Namespace) -> int:
    if args.workers < 1:
        raise UserError(f"--workers = {args.workers} must be at least 1")
    names = scenarios.available() if args.scenario == "all" else [args.scenario]
    plans = []
    for name in names:  # every scenario, option, output folder and summary checked first
        loaded = scenarios.load(name)
        loaded.check_step(args.step)
        variants = selected_variants(loaded, args.variants)
        for loss_set, scenario in losses.loss_sets(loaded, args.losses):
            for name in variants:
                variant = scenario.variant(name)
                master.check_names(scenario, variant, scenario.parameters | variant.parameters)
            folder = losses.result_folder(args.out, scenario, loss_set)
            results.check_result_set(folder)
            plans.append((scenario, variants, folder))
    run_all(plans, args.step, args.out, args.workers, args.quiet)
    return 0
