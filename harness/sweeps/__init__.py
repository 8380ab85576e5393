"""Parameter sweeps on Dask: `python -m harness sweep SWEEP.toml` (docs/sweeps.md).

A sweep file (harness/sweeps/*.toml) names a scenario, its variants, parameter axes, the
metrics to keep and the plots to draw. The package holds its three parts:

- `harness.sweeps.definition`: the sweep file (parsing and checks), the configuration paths
  its axes set, and the plan of runs (grid or Latin-hypercube sample) with stable run ids;
- `harness.sweeps.execution`: the runs on a Dask cluster, each finished chunk stored
  atomically so that a killed sweep resumes, and the consolidated tables;
- `harness.sweeps.plots`: the figures of the [plots] tables, from the consolidated table.

This module is the command: it runs the missing runs, then writes the tables and plots.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd
from distributed import Client

from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.run import results
from harness.sweeps import definition, execution, plots
from harness.sweeps.execution import CHUNKS_PER_WORKER, SWEEP_RESULTS_DIR

SCHEDULER_TIMEOUT = 10.0           # [s] to connect to a --scheduler


def connect(scheduler: str) -> Client:
    """A Client of the scheduler at an address; UserError naming --scheduler when the address
    is not one or nothing there answers as a Dask scheduler within SCHEDULER_TIMEOUT."""
    from distributed.comm import registry
    from distributed.comm.addressing import parse_address

    try:
        scheme, location = parse_address(scheduler, strict=True)
    except ValueError:
        scheme, location = "", ""
    if scheme not in registry.backends or not location:
        raise UserError(f"--scheduler = {scheduler!r} is not an address <protocol>://<host>:"
                        f"<port> with a protocol of {', '.join(registry.backends)}")
    try:
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT)
    except Exception as error:  # noqa: BLE001 - whatever a wrong address answers with
        raise UserError(f"--scheduler = {scheduler!r}: no Dask scheduler answered within "
                        f"{SCHEDULER_TIMEOUT:g} s ({error.__class__.__name__}: "
                        f"{' '.join(str(error).split())[:200]})") from None


def check_table(sweep: definition.Sweep, out: Path, replace: bool = False) -> None:
    """UserError, unless replace, where out already holds the sweep's table with rows the
    sweep does not plan (a variant at axis values it does not run: a sweep file edited, or
    another of the same name), which its table would lose."""
    path = out / f"{sweep.name}.parquet"
    if replace or not path.is_file():
        return
    axes = [axis.name for axis in sweep.axes]
    try:
        table = pd.read_parquet(path, columns=["variant", *axes])
    except (OSError, ValueError, KeyError) as error:
        raise UserError(f"{path} cannot be read as this sweep's table ({error}): write to "
                        "another --out, or add --replace") from None
    planned = {(run.variant, *(run.values[a] for a in axes)) for run in definition.plan(sweep)}
    dropped = {row for row in table.itertuples(index=False, name=None)} - planned
    if dropped:
        raise UserError(f"{path} holds a sweep made with other settings ({len(dropped)} of its "
                        f"{len(table)} rows are not in {sweep.name}'s plan): write to another "
                        "--out, or add --replace")


def run_sweep(path: str | Path, out: Path = SWEEP_RESULTS_DIR, workers: int = 2,
              scheduler: str | None = None, chunk_size: int | None = None,
              retry_failed: bool = False, quiet: bool = False,
              replace: bool = False) -> pd.DataFrame:
    """Run the missing runs of a sweep file, then write its tables and plots into out
    (`check_table`: unless replace, not over a table of runs it does not plan)."""
    sweep = definition.load(path)
    results.check_writable(out)  # before the runs, not when their rows are stored
    check_table(sweep, out, replace)
    todo = execution.pending(sweep, out, retry_failed)
    if not quiet:
        total = len(definition.plan(sweep))
        print(f"{sweep.name}: {total} runs, {total - len(todo)} stored, {len(todo)} to do")
    if todo:
        for model in {sweep.scenario.variant(v).model or sweep.scenario.model
                      for v in sweep.variants}:
            fmu_build.locate(model)  # a missing FMU is one error here, not one per worker
        client = execution.local_client(workers) if scheduler is None else connect(scheduler)
        try:
            execution.execute(sweep, todo, out, client, chunk_size, quiet)
        finally:
            execution.close_client(client)
    table = execution.consolidate(sweep, out)
    written = [out / f"{sweep.name}.parquet", out / f"{sweep.name}.csv",
               *plots.plot(sweep, table, out)]
    if not quiet:
        print("\n".join(str(p) for p in written))
        counts = table.status.value_counts()
        print(f"{len(table)} rows: {counts.get('ok', 0)} ok, {counts.get('failed', 0)} failed")
    return table


# ---- command ------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", help="sweep TOML file, or the name of one in harness/sweeps")
    parser.add_argument("--workers", type=int, default=2,
                        help="local worker processes (default 2; ignored with --scheduler)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="dask.distributed scheduler address, e.g. tcp://host:8786 "
                             "(default: local workers)")
    parser.add_argument("--chunk-size", type=int,
                        help="runs per task (default: the file's chunk_size, at most 8, and "
                             f"at least {CHUNKS_PER_WORKER} tasks per worker)")
    parser.add_argument("--retry-failed", action="store_true",
                        help="run again the runs stored as failed")
    parser.add_argument("--out", type=Path, default=SWEEP_RESULTS_DIR,
                        help="results folder (default results/sweeps)")
    parser.add_argument("--replace", action="store_true",
                        help="write the sweep's table even where OUT holds one of runs it does "
                             "not plan (without it that is refused)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def run(args: argparse.Namespace) -> int:
    if args.workers < 1 or (args.chunk_size is not None and args.chunk_size < 1):
        raise UserError("--workers and --chunk-size must be at least 1")
    try:
        table = run_sweep(args.file, args.out, args.workers, args.scheduler, args.chunk_size,
                          args.retry_failed, args.quiet, args.replace)
    except KeyboardInterrupt:
        print("interrupted: finished chunks are stored; run the same command to resume",
              file=sys.stderr)
        return 130
    if len(table) and not (table.status == "ok").any():
        print(f"error: all {len(table)} runs failed; the first: {table.error.iloc[0]}",
              file=sys.stderr)
        return 1
    return 0
