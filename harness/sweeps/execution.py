"""Running a sweep on Dask and storing its rows without losing any (docs/sweeps.md).

Execution: dask.distributed, a LocalCluster of single-threaded worker processes (pythonfmu
runs one interpreter per process, so never threads) or a given cluster; workers must be able
to import `harness` and find built FMUs (run `python -m harness build-fmus` there first). A
task runs a chunk of runs; each worker process keeps one instance per FMU model and resets it
between runs (an instance that failed is freed and replaced).

Results: one row per run (point and variant) with run_id, point, variant, the axis values,
status ("ok" or "failed"), error, the kept metrics, the FMU's calculated parameters (e.g.
payload_max), the final values of the mechanism outputs listed in `outputs` (NaN where the
variant's model has no such output), the number of FMU log messages and the first one, and
the wall time [s]. A run fails, and its row says why, when its configuration or the FMU
refuses a value (a UserError, FMUCallError included) or its worker process dies; any other
exception is a defect of the harness and stops the sweep with its traceback.

The client writes each finished chunk atomically as <out>/<name>/part-*.parquet; a restart
skips the run_ids found there, so a killed sweep loses at most the chunks in flight (rows of
runs no longer in the plan stay in the parts but leave the tables). Failed runs are not
retried on restart (bad parameters fail again), unless asked. At the end every stored row of
the plan is consolidated, in plan order, into <out>/<name>.parquet and .csv (atomically).
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import math
import multiprocessing.resource_tracker
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
from distributed import Client, KilledWorker, LocalCluster, WorkerPlugin, as_completed
from tqdm import tqdm

from harness import interrupts
from harness.engines import fmpy_master
from harness.engines.plan import prepare
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.fmu.loader import CoSimFMU, FMUCallError
from harness.io import write_atomic, write_csv
from harness.run import results
from harness.sweeps.definition import RUN_METRICS, Run, Sweep, assignments, plan
from harness.sweeps.paths import configure

SWEEP_RESULTS_DIR = results.RESULTS_DIR / "sweeps"
CHUNKS_PER_WORKER = 4              # at least this many tasks per worker, for load balance


# ---- worker side --------------------------------------------------------------------------
_FMUS: dict[str, CoSimFMU] = {}  # per worker process: model -> instance, reused across runs


def _close_fmus() -> None:
    """Free every instance of this process (at its end: a refused fmi2Terminate is logged,
    as no run is left to fail)."""
    for model in list(_FMUS):
        try:
            discard(model)
        except FMUCallError as refused:
            logging.getLogger(__name__).warning("%s", refused)


class CloseFMUs(WorkerPlugin):
    """Frees a Dask worker's FMU instances (and their extracted files) when it closes;
    atexit does not run in worker processes."""

    name = "harness.sweeps.CloseFMUs"

    def teardown(self, worker: Any) -> None:
        _close_fmus()


def model_instance(model: str) -> CoSimFMU:
    """This process's instance of the model, made on first use (freed at exit)."""
    if model not in _FMUS:
        if not _FMUS:
            atexit.register(_close_fmus)
        _FMUS[model] = CoSimFMU(fmu_build.locate(model), f"sweep.{model}")
    return _FMUS[model]


def warm_up(model: str) -> None:
    """Instantiate the model in this worker process (e.g. before timing a benchmark)."""
    model_instance(model)


def discard(model: str) -> None:
    """Free this process's instance of the model, if it has one (after a failure it may be
    unusable; the next run makes a new one). CoSimFMU.close skips freeing after a Fatal and
    raises a refused fmi2Terminate (once the instance is freed)."""
    if model in _FMUS:
        _FMUS.pop(model).close()


def run_one(sweep: Sweep, run: Run) -> dict[str, Any]:
    """Co-simulate one run. A value its configuration or its FMU refuses (a UserError,
    FMUCallError included) makes a failed row naming it; any other exception is a defect of
    the harness and propagates."""
    start = time.perf_counter()
    row: dict[str, Any] = {"run_id": run.run_id, "point": run.point, "variant": run.variant,
                           **run.values}
    model = None
    try:
        scenario, motor, design = configure(sweep.scenario, assignments(sweep, run.values))
        variant = scenario.variant(run.variant)
        model = variant.model or scenario.model
        fmu = model_instance(model)
        fmu.messages.clear()
        result = fmpy_master.run(prepare(scenario, variant, sweep.step_size, motor=motor,
                                         design=design), fmu=fmu)
        row.update(status="ok", error="", **result.metrics,
                   **fmu.get(fmu.names("calculatedParameter")),
                   **{name: float(result.series[name].iloc[-1]) if name in result.series
                      else math.nan for name in sweep.outputs},
                   fmu_messages=len(result.messages),
                   first_message=result.messages[0] if result.messages else "")
    except UserError as error:  # recorded, and the sweep goes on
        details = [f"{error.__class__.__name__}: {error}"]
        if model in _FMUS:
            if not isinstance(error, FMUCallError):  # that one carries the FMU's messages
                details += [m.message for m in _FMUS[model].messages
                            if m.status in ("Error", "Fatal")]
            try:
                discard(model)
            except FMUCallError as refused:  # the failed run's end: part of its row
                details.append(str(refused))
        row.update(status="failed", error=" ".join("; ".join(details).split()))
    row["seconds"] = time.perf_counter() - start
    return row


def run_chunk(sweep: Sweep, runs: Sequence[Run]) -> list[dict[str, Any]]:
    """One Dask task: a chunk of runs in this worker process."""
    return [run_one(sweep, run) for run in runs]


# ---- stored results -----------------------------------------------------------------------
def parts_dir(sweep: Sweep, out: Path) -> Path:
    return out / sweep.name


def stored_rows(folder: Path, key: list[str]) -> pd.DataFrame:
    """Every row in a folder's parts (`store_rows`), one per key: of a key stored twice (a
    retried run), the later one; no parts, no rows (the key's columns and status)."""
    parts = sorted(folder.glob("part-*.parquet"))
    if not parts:
        return pd.DataFrame(columns=[*key, "status"])
    table = pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True)
    return table.drop_duplicates(key, keep="last").reset_index(drop=True)


def store_rows(folder: Path, rows: list[dict[str, Any]], tag: str) -> Path:
    """Store finished rows atomically as folder/part-<time>-<tag>.parquet; part names sort
    in the order they were written."""
    path = folder / f"part-{time.time_ns():020d}-{tag}.parquet"
    frame = pd.DataFrame(rows)
    return write_atomic(path, lambda tmp: frame.to_parquet(tmp, index=False))


def stored(sweep: Sweep, out: Path) -> pd.DataFrame:
    """Every row in the sweep's parts; of a run stored twice (retried), the later one."""
    return stored_rows(parts_dir(sweep, out), ["run_id"])


def write_part(sweep: Sweep, out: Path, rows: list[dict[str, Any]]) -> Path:
    """Store finished rows atomically (`store_rows`)."""
    return store_rows(parts_dir(sweep, out), rows, rows[0]["run_id"][:8])


def pending(sweep: Sweep, out: Path, retry_failed: bool = False) -> list[Run]:
    """The planned runs without a stored row (or with a failed one, if retry_failed)."""
    table = stored(sweep, out)
    done = set(table.run_id if not retry_failed else table.run_id[table.status == "ok"])
    return [run for run in plan(sweep) if run.run_id not in done]


def execute(sweep: Sweep, runs: Sequence[Run], out: Path, client: Client,
            chunk_size: int | None = None, quiet: bool = False) -> tuple[int, int]:
    """Run on the Dask client, storing each finished chunk; returns (runs done, failed).

    A chunk whose worker process died (a run crashed it, also on the retries Dask makes
    elsewhere) is stored as failed runs; an exception raised by a task is a defect of the
    harness and propagates (the runs still in flight are cancelled).
    """
    if not runs:
        return 0, 0
    workers = max(1, sum(client.nthreads().values()))
    size = chunk_size or min(sweep.chunk_size,
                             max(1, math.ceil(len(runs) / (CHUNKS_PER_WORKER * workers))))
    chunks = [list(runs[i:i + size]) for i in range(0, len(runs), size)]
    with interrupts.deferred():  # not amid the plugin's broadcast to the workers
        client.register_plugin(CloseFMUs())
        futures = {client.submit(run_chunk, sweep, chunk, pure=False): chunk
                   for chunk in chunks}
    done = failed = 0
    with tqdm(total=len(runs), unit="run", disable=quiet, desc=sweep.name) as bar:
        bar.set_postfix(failed=0)
        try:
            for future in as_completed(futures):
                try:
                    rows = future.result()
                except KilledWorker as error:  # the task, not a run, failed
                    rows = [{"run_id": r.run_id, "point": r.point, "variant": r.variant,
                             **r.values, "status": "failed",
                             "error": f"{error.__class__.__name__}: {error}"}
                            for r in futures[future]]
                write_part(sweep, out, rows)
                done += len(rows)
                failed += sum(row["status"] == "failed" for row in rows)
                bar.update(len(rows))
                bar.set_postfix(failed=failed)
        finally:
            client.cancel(list(futures))
    return done, failed


def consolidate(sweep: Sweep, out: Path) -> pd.DataFrame:
    """The rows of the planned runs, in plan order, written to <name>.parquet and .csv."""
    runs = plan(sweep)
    table = stored(sweep, out).set_index("run_id")
    table = table.reindex([r.run_id for r in runs if r.run_id in table.index]).reset_index()
    axes = [a.name for a in sweep.axes]
    last = ["fmu_messages", "first_message", "seconds"]
    extra = [c for c in table.columns if c not in {"run_id", "point", "variant", "status",
                                                   "error", *last, *axes, *RUN_METRICS}]
    columns = ["run_id", "point", "variant", *axes, "status", "error", *sweep.metrics,
               *extra, *last]
    table = table.reindex(columns=columns)
    out.mkdir(parents=True, exist_ok=True)
    # both files into one temporary folder, then renamed one after the other: the window in
    # which a kill leaves them with different rows is two renames, not a whole CSV write
    with tempfile.TemporaryDirectory(dir=out, prefix=f".{sweep.name}.") as tmp:
        staged = Path(tmp)
        table.to_parquet(staged / "table.parquet", index=False)
        write_csv(table, staged / "table.csv")
        for suffix in ("parquet", "csv"):
            (staged / f"table.{suffix}").chmod(0o644)
            (staged / f"table.{suffix}").replace(out / f"{sweep.name}.{suffix}")
    return table


# ---- driver -------------------------------------------------------------------------------
def local_client(workers: int) -> Client:
    """A distributed Client on a LocalCluster of single-threaded worker processes. Its
    processes and threads start with SIGINT blocked: a Ctrl-C stops the sweep here, which
    stores the finished chunks and closes the cluster, instead of killing a worker midway."""
    # started first, as its start unblocks SIGINT in the thread that starts it
    multiprocessing.resource_tracker.ensure_running()
    client = None
    try:
        with interrupts.deferred(), interrupts.blocked():  # not amid the cluster's start
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster)
    except KeyboardInterrupt:
        if client is not None:
            close_client(client)
        raise
    return client


def close_client(client: Client) -> None:
    """Close the client and its local cluster. After Ctrl-C the workers may be gone already:
    a closed connection (CommClosedError, an OSError) is then expected, not an error."""
    cluster = client.cluster
    with contextlib.suppress(OSError):
        client.close()
        if cluster is not None:
            cluster.close()
