"""A study's runs on Dask, stored so that a killed study resumes without losing or repeating
a row (docs/study.md).

The drives: each variant's drive on each joint is chosen once per study by the sizing rule
of the headline tables (`harness.run.sizing`, docs/drives.md) over the study's first
`drive_sample` tasks in both loss sets (the worst of each figure), and pinned in every task's
file, so that a task reruns alone in `cosim` with them.

The runs: one Dask task per study task runs every (variant, loss set) of it not yet stored,
in the FMPy master at the study's step, each worker reusing one instance per FMU model
(`harness.sweeps.execution`). Each finished task's rows are written at once, atomically, as
<study>/parts/part-<time>-<task>.parquet; a restart runs only the (task, variant, losses)
without a row, and the table keeps one row per key. A run whose FMU or configuration
refuses a value is a failed row naming it, as in a sweep.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
from distributed import Client, KilledWorker, as_completed
from tqdm import tqdm

from harness import interrupts
from harness.drive.metrics import TOTALS
from harness.engines import fmpy_master
from harness.engines.plan import prepare
from harness.errors import UserError
from harness.fmu.loader import FMUCallError
from harness.run import sizing
from harness.study.tasks import Task
from harness.sweeps.execution import (
    CloseFMUs,
    discard,
    model_instance,
    store_rows,
    stored_rows,
)

KEY = ("task", "variant", "losses")
# the run's figures a row keeps: the energies summed over the drives, the drives' verdict
KEPT = (*TOTALS, "drive_ok")


def size_variant(sample: Sequence[Task], variant: str, step: float) -> dict[str, dict[str, Any]]:
    """The variant's drive on each joint by the sizing rule over the sample tasks' loss sets,
    as the `drives` pins of a task file ({joint: {motor, gearhead, ratio}}), and the rows of
    drives.csv."""
    loss_sets = [scenario for task in sample for _, scenario in task.loss_sets()]
    sized = sizing.size_variant(loss_sets, variant, step)
    return {joint: {"pin": s.drive.pin(), "row": sizing.table_row(variant, joint, s)}
            for joint, s in sized.items()}


def run_one(task: Task, variant: str, loss_set: str, step: float) -> dict[str, Any]:
    """One (task, variant, loss set) in the FMPy master with the pinned drives: its row."""
    start = time.perf_counter()
    row: dict[str, Any] = {"task": task.row["task"], "variant": variant, "losses": loss_set}
    model = None
    try:
        scenario = dict(task.loss_sets())[loss_set]
        chosen = scenario.variant(variant)
        model = chosen.model or scenario.model
        resolved = scenario.for_variant(chosen)
        drives = sizing.pinned_drives(resolved, loss_set, f"{task.name} variant {variant}")
        fmu = model_instance(model)
        result = fmpy_master.run(prepare(scenario, chosen, step, drives), fmu=fmu, series=False)
        row.update(status="ok", error="", duration=resolved.duration,
                   **{name: result.metrics[name] for name in KEPT})
    except UserError as error:  # recorded, and the study goes on
        row.update(status="failed", error=" ".join(f"{type(error).__name__}: {error}".split()))
        if model is not None:
            try:
                discard(model)
            except FMUCallError as refused:  # the failed run's end: part of its row
                row["error"] += f"; {' '.join(str(refused).split())}"
    row["seconds"] = time.perf_counter() - start
    return row


def run_task(task: Task, jobs: Sequence[tuple[str, str]], step: float) -> list[dict[str, Any]]:
    """One Dask task: the given (variant, loss set) runs of a study task."""
    return [run_one(task, variant, loss_set, step) for variant, loss_set in jobs]


def parts_dir(folder: Path) -> Path:
    return folder / "parts"


def stored(folder: Path) -> pd.DataFrame:
    """Every stored row, one per key (the later of a key stored twice)."""
    return stored_rows(parts_dir(folder), list(KEY))


def write_part(folder: Path, rows: list[dict[str, Any]]) -> Path:
    """Store a finished task's rows atomically (`store_rows`)."""
    return store_rows(parts_dir(folder), rows, f"{rows[0]['task']:05d}")


def pending(folder: Path, tasks: Sequence[Task], variants: Sequence[str],
            loss_sets: Sequence[str], retry_failed: bool = False
            ) -> dict[int, list[tuple[str, str]]]:
    """Per task index, the (variant, loss set) runs without a stored row (or with a failed
    one, if retry_failed)."""
    table = stored(folder)
    if retry_failed:
        table = table[table.status == "ok"]
    done = set(zip(table.task, table.variant, table.losses))
    todo = {task.row["task"]: [(v, ls) for v in variants for ls in loss_sets
                               if (task.row["task"], v, ls) not in done] for task in tasks}
    return {index: jobs for index, jobs in todo.items() if jobs}


def execute(folder: Path, tasks: Sequence[Task], todo: dict[int, list[tuple[str, str]]],
            step: float, client: Client, quiet: bool = False) -> tuple[int, int]:
    """Run the pending runs on the client, storing each finished task's rows; returns (runs
    done, failed). A task whose worker died is stored as failed runs."""
    by_index = {task.row["task"]: task for task in tasks}
    total = sum(len(jobs) for jobs in todo.values())
    if not total:
        return 0, 0
    with interrupts.deferred():  # not amid the plugin's broadcast to the workers
        client.register_plugin(CloseFMUs())
        futures = {client.submit(run_task, by_index[index], jobs, step, pure=False):
                   (index, jobs) for index, jobs in todo.items()}
    done = failed = 0
    # a SIGINT or SIGTERM stops the study once the task in flight that ends first is stored
    with interrupts.deferred(), tqdm(total=total, unit="run", disable=quiet,
                                     desc="study") as bar:
        bar.set_postfix(failed=0)
        try:
            for future in as_completed(futures):
                try:
                    rows = future.result()
                except KilledWorker as error:
                    index, jobs = futures[future]
                    rows = [{"task": index, "variant": v, "losses": ls, "status": "failed",
                             "error": f"{type(error).__name__}: {error}"} for v, ls in jobs]
                write_part(folder, rows)
                done += len(rows)
                failed += sum(row["status"] == "failed" for row in rows)
                bar.update(len(rows))
                bar.set_postfix(failed=failed)
                interrupts.stop_if_requested()
        finally:
            client.cancel(list(futures))
    return done, failed


def runs_table(folder: Path, tasks: Sequence[Task], variants: Sequence[str],
               loss_sets: Sequence[str], baselines: dict[str, str]) -> pd.DataFrame:
    """The stored rows of the planned runs in plan order (task, loss set, variant), with
    eps against each variant's baseline in the same task and loss set."""
    table = stored(folder).set_index(list(KEY))
    keys = [(t.row["task"], v, ls) for t in tasks for ls in loss_sets for v in variants]
    table = table.reindex([k for k in keys if k in table.index]).reset_index()
    drawn = table.set_index(list(KEY))["E_drawn"] if len(table) else pd.Series(dtype=float)
    table["eps"] = [1.0 - row.E_drawn / drawn.get((row.task, baselines[row.variant],
                                                     row.losses), math.nan)
                    for row in table.itertuples()]
    columns = [*KEY, "status", "error", "duration", *KEPT, "eps", "seconds"]
    return table.reindex(columns=columns)
