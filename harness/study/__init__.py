"""The study: every variant of a scenario over a distribution of random tasks, with
confidence intervals, on Dask: `python -m harness study` (docs/study.md).

The room's parts:
- `harness.study.model`: the task model, as data (harness/study/<scenario>.toml);
- `harness.study.tasks`: tasks drawn from it, each written as a scenario file;
- `harness.study.execution`: the drives sized once per study, the runs on Dask, each
  finished task's rows stored atomically so that a killed study resumes;
- `harness.study.statistics` and `harness.study.plots`: the tables and figures.

This module is the command. Output in OUT/<scenario>/: settings.json (what the runs depend
on: a study resumes only with the same), tasks/ (each task's scenario file, its realistic
loss file in tasks/realistic/), tasks.csv (one row per task), drives.csv (each variant's
drives), runs.csv (one row per task, variant and loss set), summary.csv,
paired.csv, dependence.csv, energy.png and dependence.png.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shlex
import shutil
import signal
import sys
from collections.abc import Callable
from pathlib import Path

import pandas as pd
from distributed import Client, as_completed
from tqdm import tqdm

from harness import interrupts, scenarios
from harness.errors import UserError
from harness.fmu import build as fmu_build
from harness.io import save_figure, write_atomic, write_csv
from harness.run import results
from harness.run.sizing import stored_pins
from harness.scenarios import losses
from harness.study import execution, model, plots, statistics, tasks
from harness.study.tasks import Task
from harness.sweeps import connect
from harness.sweeps.execution import close_client, local_client

STUDY_DIR = results.RESULTS_DIR / "study"
SETTINGS = "settings.json"   # what the stored runs depend on (`settings`)
MAX_TASKS = 100_000
DEFAULT_SEED = 1


def task_rows(drawn: list[Task], folder: Path, step: float) -> pd.DataFrame:
    """tasks.csv: each task's figures, its file and the command that reruns it alone."""
    rows = []
    for task in drawn:
        path = folder / "tasks" / f"{task.name}.toml"
        rows.append({**task.row, "file": str(path.relative_to(folder)), "rerun": shlex.join([
            "python", "-m", "harness", "cosim", "--scenario", _shown(path), "--step",
            repr(step), "--out", "build/study-rerun"])})
    return pd.DataFrame(rows)


def _shown(path: Path) -> str:
    """A path relative to the working directory where it is inside it."""
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def drive_pins(task_model: model.TaskModel, seed: int, folder: Path,
               client: Callable[[], Client], quiet: bool) -> dict[str, dict[str, dict]]:
    """Each variant's drives: those of folder/drives.csv, else sized on the study's first
    drive_sample tasks (one Dask task per variant, whatever the number of tasks run) and
    written there."""
    path = folder / "drives.csv"
    if not path.exists():
        sample = [tasks.draw(task_model, seed, i) for i in range(task_model.drive_sample)]
        variants = list(task_model.template.variants)
        futures = {client().submit(execution.size_variant, sample, v, task_model.step,
                                   pure=False): v for v in variants}
        sized = {}
        with tqdm(total=len(futures), unit="variant", disable=quiet,
                  desc=f"{task_model.name}: sizing on {len(sample)} tasks") as bar:
            for future in as_completed(futures):
                sized[futures[future]] = future.result()
                bar.update()
        sized = {v: sized[v] for v in variants}
        rows = pd.DataFrame([joint["row"] for v in variants for joint in sized[v].values()])
        folder.mkdir(parents=True, exist_ok=True)
        write_csv(rows, path)
    return stored_pins(path)


def settings(task_model: model.TaskModel, seed: int, n_tasks: int) -> dict[str, object]:
    """What a study's stored runs and tables depend on: the seed, the number of tasks, and the
    text of the task model, of its scenario and of the scenario's loss file."""
    files = [model.STUDY_DIR / f"{task_model.name}.toml",
             scenarios.scenario_file(task_model.template.name)]
    if losses.has_realistic(task_model.template):
        files.append(losses.loss_file(task_model.template))
    digest = hashlib.sha256(b"".join(path.read_bytes() for path in files)).hexdigest()
    return {"seed": seed, "tasks": n_tasks, "step": task_model.step,
            "drive_sample": task_model.drive_sample,
            "files": [str(path.relative_to(results.RESULTS_DIR.parent)) for path in files],
            "sha256": digest}


def stored_settings(folder: Path) -> dict[str, object] | None:
    """The settings a study folder records (`settings`), None where it records none;
    UserError naming the file when it cannot be read."""
    path = folder / SETTINGS
    if not path.exists():
        return None
    try:
        stored = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise UserError(f"{path} cannot be read ({error}): move it away, or add --replace to "
                        "start the study anew") from None
    if not isinstance(stored, dict):
        raise UserError(f"{path} is not a table of settings: move it away, or add --replace "
                        "to start the study anew")
    return stored


def check_settings(folder: Path, wanted: dict[str, object], replace: bool = False) -> None:
    """Refuse a folder whose study was made with other settings (`settings`), in one line
    naming them, --out and --replace; then record them. replace: where only the number of
    tasks differs, the stored runs are kept and the tables rewritten for the new number;
    otherwise the folder's study is removed first."""
    stored = stored_settings(folder)
    changed = [key for key in wanted if stored is not None and stored.get(key) != wanted[key]]
    if changed and not replace:
        what = ", ".join(f"{key} {stored.get(key)!r} -> {wanted[key]!r}" for key in changed)
        raise UserError(f"{folder} holds a study made with other settings ({what}): write to "
                        "another --out (runs the committed study holds are reused), or add "
                        "--replace")
    if changed and changed != ["tasks"]:
        for path in (folder / "parts", folder / "tasks"):
            shutil.rmtree(path, ignore_errors=True)
        (folder / "drives.csv").unlink(missing_ok=True)
    if stored != wanted:
        folder.mkdir(parents=True, exist_ok=True)
        write_atomic(folder / SETTINGS,
                     lambda tmp: tmp.write_text(json.dumps(wanted, indent=1) + "\n"))


def reusable_study(folder: Path, wanted: dict[str, object]) -> Path | None:
    """The committed study (STUDY_DIR/<scenario>) whose drives and runs a study in another
    folder reuses: one made with the same settings but for the number of tasks."""
    source = STUDY_DIR / folder.name
    if source.resolve() == folder.resolve() or not (source / "runs.csv").is_file():
        return None
    stored = stored_settings(source) or {}
    same = all(stored.get(key) == value for key, value in wanted.items() if key != "tasks")
    return source if same else None


def reuse(source: Path, folder: Path, drawn: list[Task], variants: list[str],
          loss_sets: list[str]) -> int:
    """Copy the committed study's drives.csv into folder where it has none, and store the
    rows of its runs.csv that folder's tasks need and folder lacks (runs.csv's 10 digits);
    the number of runs reused."""
    if not (folder / "drives.csv").exists():
        folder.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / "drives.csv", folder / "drives.csv")
    wanted = execution.pending(folder, drawn, variants, loss_sets)
    rows = pd.read_csv(source / "runs.csv", dtype={"error": str}).drop(columns="eps")
    rows = rows.fillna({"error": ""})
    keys = {(task, v, ls) for task, jobs in wanted.items() for v, ls in jobs}
    found = rows[[key in keys for key in zip(rows.task, rows.variant, rows.losses)]]
    if len(found):
        execution.write_part(folder, found.to_dict("records"))
    return len(found)


def run_study(name: str, n_tasks: int | None, seed: int, out: Path,
              client: Callable[[], Client], quiet: bool = False,
              retry_failed: bool = False, replace: bool = False) -> pd.DataFrame:
    """Run what is missing of a scenario's study in out/<name>/ (with retry_failed, also the
    runs stored as failed; reusing what the committed study holds, `reusable_study`), then
    write its tables and figures; returns the runs."""
    task_model = model.load(name)
    n = n_tasks or task_model.tasks
    folder = out / name
    results.check_writable(out)
    wanted = settings(task_model, seed, n)
    check_settings(folder, wanted, replace)
    drawn = [tasks.draw(task_model, seed, i) for i in range(n)]
    variants = list(task_model.template.variants)
    loss_sets = [ls for ls, _ in losses.loss_sets(task_model.template, "all")]
    source = reusable_study(folder, wanted)
    reused = 0 if source is None else reuse(source, folder, drawn, variants, loss_sets)
    pins = drive_pins(task_model, seed, folder, client, quiet)
    drawn = [tasks.pinned(task, pins) for task in drawn]
    for task in drawn:
        tasks.write(task, folder / "tasks")
    write_csv(task_rows(drawn, folder, task_model.step), folder / "tasks.csv")
    todo = execution.pending(folder, drawn, variants, loss_sets, retry_failed)
    if not quiet:
        total = n * len(variants) * len(loss_sets)
        left = sum(len(jobs) for jobs in todo.values())
        print(f"{name}: {n} tasks, {total} runs, {total - left} stored"
              + (f" ({reused} from {_shown(source)})" if reused else "") + f", {left} to do")
    if todo:
        execution.execute(folder, drawn, todo, task_model.step, client(), quiet)
    return write_tables(task_model, drawn, folder, variants, loss_sets, quiet)


def write_tables(task_model: model.TaskModel, drawn: list[Task], folder: Path,
                 variants: list[str], loss_sets: list[str], quiet: bool) -> pd.DataFrame:
    """Write the study's tables and figures; returns runs.csv's table."""
    template = task_model.template
    runs = execution.runs_table(folder, drawn, variants, loss_sets, template.baselines)
    task_table = pd.read_csv(folder / "tasks.csv")
    summary = statistics.summary(runs, variants, task_model.reference)
    dependence = statistics.dependence(runs, task_table, variants, task_model.reference)
    written = [write_csv(runs, folder / "runs.csv"), write_csv(summary, folder / "summary.csv"),
               write_csv(statistics.paired(runs, variants), folder / "paired.csv"),
               write_csv(dependence, folder / "dependence.csv"),
               save_figure(plots.energy_figure(template.name, runs, variants, len(drawn)),
                           folder / "energy.png")]
    figure = plots.dependence_figure(template.name, dependence, task_model.reference)
    if figure is not None:
        written.append(save_figure(figure, folder / "dependence.png"))
    if not quiet:
        print("\n".join(str(p) for p in written))
        failed = int((runs.status != "ok").sum())
        print(f"{len(runs)} runs: {len(runs) - failed} ok, {failed} failed")
    return runs


# ---- command ------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.epilog = "task models: " + ", ".join(model.available())
    parser.add_argument("--scenario", default="all",
                        help="a scenario with a task model (harness/study/<name>.toml) or 'all'")
    parser.add_argument("--tasks", type=int,
                        help="tasks to draw (default: the task model's, that of the committed "
                             "study)")
    parser.add_argument("--seed", type=int, default=DEFAULT_SEED,
                        help="the tasks' seed: task i comes from numpy's default_rng([seed, i])")
    parser.add_argument("--workers", type=int, default=2,
                        help="local worker processes (ignored with --scheduler)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="dask.distributed scheduler address, e.g. tcp://host:8786 "
                             "(default: local workers)")
    parser.add_argument("--out", type=Path, default=STUDY_DIR,
                        help="results folder: the study goes to OUT/<scenario>/")
    parser.add_argument("--retry-failed", action="store_true",
                        help="run again the runs stored as failed")
    parser.add_argument("--replace", action="store_true",
                        help="write into a folder whose study was made with other settings "
                             "(without it such a folder is refused): its runs are kept when "
                             "only --tasks differs, else the study starts anew")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def run(args: argparse.Namespace) -> int:
    if args.tasks is not None and not 1 <= args.tasks <= MAX_TASKS:
        raise UserError(f"--tasks = {args.tasks} is outside [1, {MAX_TASKS:,}]")
    if not 0 <= args.seed < 2 ** 63:
        raise UserError(f"--seed = {args.seed} is outside [0, 2**63 - 1]")
    if args.workers < 1:
        raise UserError(f"--workers = {args.workers} must be at least 1")
    names = model.available() if args.scenario == "all" else [args.scenario]
    for name in names:
        task_model = model.load(name)  # every task model checked before anything runs
        for variant in task_model.template.variants.values():
            fmu_build.locate(variant.model or task_model.template.model)
    clients: list[Client] = []

    def client() -> Client:
        if not clients:
            clients.append(local_client(args.workers) if args.scheduler is None
                           else connect(args.scheduler))
        return clients[0]

    try:
        for name in names:
            runs = run_study(name, args.tasks, args.seed, args.out, client, args.quiet,
                             args.retry_failed, args.replace)
            if not (runs.status == "ok").any():
                print(f"error: all {len(runs)} runs of {name} failed; the first: "
                      f"{runs.error.iloc[0]}", file=sys.stderr)
                return 1
    except KeyboardInterrupt:   # SIGINT (exit 130) or SIGTERM (143), as harness.cli's
        terminated = interrupts.received == signal.SIGTERM
        print(f"{'terminated' if terminated else 'interrupted'}: the finished tasks' runs are "
              "stored; run the same command to resume", file=sys.stderr)
        return 143 if terminated else 130
    finally:
        with interrupts.deferred():
            for c in clients:
                close_client(c)
    return 0
