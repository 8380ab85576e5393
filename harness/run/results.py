"""Result files (docs/results.md): per-variant CSV series, a summary table, the time series
plot, and the scenario's headline figure drawn from every loss set's summary
(`write_energy_figure`; the figures are `harness.run.plots`).

CSVs follow the FMI cross-check conventions (as fmpy.util.write_csv): quoted header,
`time` first, one column per quantity named after the FMU variable or drive signal, SI units,
booleans as 0/1. Every file is written atomically (harness.io), so a crash never leaves a
half-written result.

A scenario's folder is one result set: `write_run` merges the variants just run into it
(their CSVs replaced, every other row of the summary kept, whatever its columns: the table
gets the union of both layouts), makes every file in a staging folder first and then renames
them into place in one burst, summary last, and holds an exclusive lock on the folder
meanwhile, so concurrent runs into one folder are serialised instead of overwriting each
other's rows. A staging folder is locked too while it is in use; one that nobody holds (its
writer was killed) is removed by the next write.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness import interrupts, registry
from harness.drive.metrics import METRICS, efficaciousness
from harness.engines.result import RunResult, suffix
from harness.errors import UserError
from harness.io import check_target, save_figure, write_csv
from harness.run import plots
from harness.scenarios import Scenario

try:
    import fcntl
except ImportError:  # not POSIX: no locks, so no serialisation and no stale-staging cleanup
    fcntl = None

RESULTS_DIR = Path(__file__).resolve().parents[2] / "results"
SETTINGS = "settings.json"  # what a result set was made with: engine, drives, step
STAGING_PREFIX = ".staging."  # write_run's staging folders inside a result set
SUMMARY_COLUMNS = ("variant", *METRICS, "W_phases", "eps_W", "model", "step_size")


def summary_outputs() -> tuple[str, ...]:
    """The mechanism outputs a summary reports at the end of the run, where a variant's model
    has them (NaN, an empty cell, for the others): every registration's summary_outputs."""
    return tuple(dict.fromkeys(name for r in registry.mechanisms().values()
                               for name in r.summary_outputs))


def summary_columns(results: list[RunResult]) -> list[str]:
    """Columns of a summary: SUMMARY_COLUMNS for one-joint runs; with several joints the
    totals, then each drive's metrics (see harness.drive.metrics), then eps and the rest. Where the
    runs differ in their joints, every metric any of them has, in order of appearance; the
    summary_outputs any of them has go before model."""
    metrics = dict.fromkeys(name for r in results for name in r.metrics)
    outputs = [name for name in summary_outputs() if any(name in r.series for r in results)]
    return ["variant", *metrics, "eps", "W_phases", "eps_W", *outputs, "model", "step_size"]


def _summary_row(run: RunResult) -> dict[str, object]:
    """A run's metrics, its summary_outputs at the end and, for a one-joint run, its drive
    metrics also under the joint-suffixed names of several-joint runs (kept where the table
    has those columns)."""
    (joint, *others) = run.joint_phase_work or [None]
    suffixed = ({f"{name}_{joint}": value for name, value in run.metrics.items()}
                if joint is not None and not others else {})
    return {**run.metrics, **suffixed,
            **{name: float(run.series[name].iloc[-1]) for name in summary_outputs()
               if name in run.series}}


def merged_columns(layout: Sequence[str], columns: Sequence[str]) -> list[str]:
    """The union of two summary layouts: layout's columns in its order, each other column
    inserted after the one it follows in columns."""
    merged = list(layout)
    for previous, column in zip([None, *columns], columns, strict=False):
        if column not in merged:
            merged.insert(0 if previous is None else merged.index(previous) + 1, column)
    return merged


def summary(results: Iterable[RunResult], baseline: str | Mapping[str, str],
            layout: Sequence[str] = ()) -> pd.DataFrame:
    """One row per variant with the metrics of docs/results.md and the per-phase work.

    Where some variants drive several joints and others one (franchetti2021's
    active_relocation), a one-joint variant's drive metrics also fill the columns of its
    joint (`E_drawn_theta`), and the drive metrics of a several-joint variant under plain
    names stay empty (NaN) unless they are totals.

    W_phases [J] is the sum over the task's phases (and drives) of |net mechanical work of the
    drive on its joint in the phase|: the paper's stroke energy |integral of M dphi| summed
    over strokes. eps (on E_drawn, docs/results.md) and eps_W (on W_phases) are computed
    against the baseline: one variant name, or a baseline per variant (Scenario.baselines);
    NaN where the baseline was not run.

    layout: the columns of the result set these rows join (write_run); the table then has
    the union of layout and its own columns (merged_columns), NaN where a run has no value.
    """
    results = list(results)
    rows = [{"variant": r.variant, **_summary_row(r),
             "W_phases": sum(abs(w) for works in r.joint_phase_work.values()
                             for w in works.values()),
             "model": r.model, "step_size": r.step_size} for r in results]
    columns = merged_columns(layout, summary_columns(results))
    return with_eps(pd.DataFrame(rows), baseline).reindex(columns=columns)


def with_eps(table: pd.DataFrame, baseline: str | Mapping[str, str]) -> pd.DataFrame:
    """The summary table with eps and eps_W computed against each row's baseline row."""
    baselines = table.variant.map(
        (lambda _: baseline) if isinstance(baseline, str) else baseline.get)
    indexed = table.set_index("variant")
    for metric, column in (("E_drawn", "eps"), ("W_phases", "eps_W")):
        table[column] = efficaciousness(table[metric], baselines.map(indexed[metric]))
    return table


@dataclass(frozen=True)
class StoredRun:
    """A variant of the result set written by an earlier run: what its plot needs."""

    variant: str
    model: str
    series: pd.DataFrame


def check_writable(out_dir: Path) -> None:
    """UserError unless files can be created in out_dir (made if missing): checked before a
    simulation, so a long run does not end in a write error."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out_dir):
            pass
    except OSError as error:
        raise UserError(f"output folder {out_dir} is not writable "
                        f"({error.strerror or error})") from None


def read_summary(path: Path) -> pd.DataFrame | None:
    """The summary table of a result set, None if there is none yet; UserError naming the
    file when it is empty, not a CSV, or lacks a variant or model in a row or repeats one."""
    if not path.exists():
        return None
    start_anew = "move it away to start a new result set"
    table = _read_csv(path, dtype={"variant": str, "model": str})
    for column in ("variant", "model"):
        if column not in table or table[column].isna().any():
            raise UserError(f"{path} has no {column} column or an empty {column} cell: "
                            f"{start_anew}")
    repeated = sorted(set(table.variant[table.variant.duplicated()]))
    if repeated:
        raise UserError(f"{path} lists variant(s) {', '.join(repeated)} twice: {start_anew}")
    return table


def check_result_set(out_dir: Path, settings: Mapping[str, object],
                     replace: bool = False) -> None:
    """UserError unless out_dir is writable, a summary.csv there is readable (read_summary)
    and its result set was made with these settings (its SETTINGS file), unless replace:
    checked before a simulation, so that no run mixes its rows into a set made otherwise."""
    check_writable(out_dir)
    if read_summary(out_dir / "summary.csv") is None or replace:
        return
    path = out_dir / SETTINGS
    try:
        stored = json.loads(path.read_text())
    except FileNotFoundError:
        stored = {}
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise UserError(f"{path} cannot be read ({error}): move it away, or add --replace "
                        "to start the result set anew") from None
    changed = [f"{key} {stored.get(key)!r}, not {value!r}" for key, value in settings.items()
               if stored.get(key) != value]
    if changed:
        raise UserError(f"{out_dir} holds a result set made with {'; '.join(changed)}: "
                        "write to another --out, or add --replace to start it anew")


@contextlib.contextmanager
def _flocked(path: Path) -> Iterator[None]:
    """Hold an exclusive flock on a file or folder (released when its holder dies)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


@contextlib.contextmanager
def locked(out_dir: Path) -> Iterator[None]:
    """Hold an exclusive lock on the folder (flock on the folder itself, so no lock file is
    left behind and a killed writer releases it): concurrent writers wait their turn."""
    out_dir.mkdir(parents=True, exist_ok=True)
    with contextlib.nullcontext() if fcntl is None else _flocked(out_dir):
        yield


@contextlib.contextmanager
def staging(out_dir: Path) -> Iterator[Path]:
    """A new staging folder in out_dir, locked while in use (so that remove_stale_staging
    tells it from one left by a killed writer) and removed after."""
    with tempfile.TemporaryDirectory(dir=out_dir, prefix=STAGING_PREFIX) as tmp:
        with contextlib.nullcontext() if fcntl is None else _flocked(Path(tmp)):
            yield Path(tmp)


def remove_stale_staging(out_dir: Path) -> list[Path]:
    """Remove the staging folders in out_dir that no live process holds (a writer killed
    while staging, e.g. by SIGKILL, leaves its folder, but its lock died with it); return
    those removed. Called with the folder lock held, so no writer is between making and
    locking one; a folder that cannot be removed stays (hidden, it holds no result)."""
    if fcntl is None:
        return []
    removed = []
    for folder in sorted(out_dir.glob(f"{STAGING_PREFIX}*")):
        if folder.is_symlink() or not folder.is_dir():
            continue
        try:
            fd = os.open(folder, os.O_RDONLY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            shutil.rmtree(folder, ignore_errors=True)  # holding its lock meanwhile
            if not folder.exists():
                removed.append(folder)
        except BlockingIOError:
            pass  # held by a live writer
        finally:
            os.close(fd)
    return removed


def write_run(results: list[RunResult], scenario: Scenario, out_dir: Path,
              loss_set: str = "ideal", drives: pd.DataFrame | None = None,
              settings: Mapping[str, object] | None = None, replace: bool = False
              ) -> list[Path]:
    """Write <variant>.csv for each run, then the plot and summary.csv of the whole result set
    in out_dir (of the loss set, which the plot's title names): every row of an earlier
    summary is kept (with the union of the columns) but the variants run now, eps is
    recomputed over all rows; replace: the set starts anew, the earlier one's files of other
    variants removed. A failure before the renames (a full disk) is a UserError naming the
    file and leaves the old set untouched; the summary is renamed last: it lists what the set
    holds. drives: the sizing rows of the variants run (harness.run.sizing.table_row), merged
    into the set's drives.csv. settings: what the set was made with, written to its SETTINGS
    file (`check_result_set`). A stop asked for before the renames (`harness.interrupts`)
    renames nothing and raises KeyboardInterrupt."""
    with locked(out_dir):
        remove_stale_staging(out_dir)
        old = None if replace else read_summary(out_dir / "summary.csv")
        try:
            with staging(out_dir) as folder:  # every file made here, then renamed in a burst
                staged = _stage(results, scenario, out_dir, old, folder, loss_set)
                if drives is not None:
                    staged.insert(-1, _stage_drives(drives, scenario, out_dir, folder,
                                                    replace))
                if settings is not None:
                    staged.insert(-1, _stage_settings(settings, folder))
                for path in staged:
                    check_target(out_dir / path.name)
                # a stop asked for meanwhile (SIGINT, SIGTERM) leaves the set as it was
                interrupts.stop_if_requested()
                written = [path.replace(out_dir / path.name) for path in staged]
                if replace:
                    _remove_others(out_dir, {path.name for path in written})
                return written
        except OSError as error:
            raise UserError(f"cannot write the result set in {out_dir}: "
                            f"{error.strerror or error}") from None
        except UserError as error:
            raise UserError(f"{error} (the result set in {out_dir} is as it was)") from None


def _stage(results: list[RunResult], scenario: Scenario, out_dir: Path,
           old: pd.DataFrame | None, folder: Path, loss_set: str) -> list[Path]:
    """Write into folder the new variants' CSVs, then the plot and the summary of the set:
    the new rows and every old row of another variant (old, the existing summary), in the
    scenario's variant order (variants it no longer has last, as they were)."""
    staged = [write_csv(r.series, folder / f"{r.variant}.csv") for r in results]
    table = summary(results, scenario.baselines, () if old is None else old.columns)
    kept = table.iloc[:0] if old is None else old[~old.variant.isin(table.variant)]
    rank = {name: index for index, name in enumerate(scenario.variants)}
    table = pd.concat([table, kept.reindex(columns=table.columns)], ignore_index=True)
    table = table.sort_values("variant", key=lambda v: v.map(lambda n: rank.get(n, len(rank))),
                              kind="stable")
    table = with_eps(table.reset_index(drop=True), scenario.baselines)
    stored = [StoredRun(variant, model, _read_csv(out_dir / f"{variant}.csv"))
              for variant, model in zip(kept.variant, kept.model, strict=True)
              if (out_dir / f"{variant}.csv").exists()]  # a row without its CSV: not plotted
    runs = sorted([*results, *stored], key=lambda r: rank.get(r.variant, len(rank)))
    staged.append(plots.plot(runs, scenario, folder / f"{scenario.name}.png", loss_set))
    staged.append(write_csv(table, folder / "summary.csv"))
    return staged


def _stage_settings(settings: Mapping[str, object], folder: Path) -> Path:
    """The set's SETTINGS file into folder."""
    path = folder / SETTINGS
    path.write_text(json.dumps(dict(settings), indent=1) + "\n")
    return path


def _remove_others(out_dir: Path, staged: set[str]) -> None:
    """Remove the files of an earlier result set in out_dir that the new set does not
    replace (its variants' CSVs, settings, drives): the set starts anew."""
    for path in out_dir.iterdir():
        if path.is_file() and path.name not in staged and (
                path.suffix == ".csv" or path.name == SETTINGS):
            path.unlink()


def _stage_drives(drives: pd.DataFrame, scenario: Scenario, out_dir: Path,
                  folder: Path, replace: bool = False) -> Path:
    """drives.csv of the set into folder: the rows of the variants run, and (unless
    replace) every other row of the set's drives.csv, in the scenario's variant order."""
    old = out_dir / "drives.csv"
    kept = _read_csv(old) if old.exists() and not replace else drives.iloc[:0]
    table = pd.concat([drives, kept[~kept.variant.isin(drives.variant)]], ignore_index=True)
    rank = {name: index for index, name in enumerate(scenario.variants)}
    table = table.sort_values("variant", key=lambda v: v.map(lambda n: rank.get(n, len(rank))),
                              kind="stable")
    return write_csv(table.reset_index(drop=True), folder / "drives.csv")


def energy_figure_path(folders: Mapping[str, Path], scenario: Scenario) -> Path:
    """Where a scenario's headline figure goes: `<scenario>_energy.png` in the folder of its
    first loss set (the ideal set's, the scenario's own folder)."""
    return next(iter(folders.values())) / f"{scenario.name}_energy.png"


def write_energy_figure(scenario: Scenario, folders: Mapping[str, Path]) -> Path:
    """Draw the scenario's headline figure (plots.energy_figure) from the summaries of its
    loss sets' result sets (folders: loss set -> folder), those that exist, at
    `energy_figure_path`. Called after each set is written, it holds the lock of the
    figure's folder while it reads and writes, so of two sets written at once the later
    drawing sees both summaries (each is renamed into place whole)."""
    path = energy_figure_path(folders, scenario)
    with locked(path.parent):
        tables = {loss_set: table for loss_set, folder in folders.items()
                  if (table := read_summary(folder / "summary.csv")) is not None}
        check_target(path)
        return save_figure(plots.energy_figure(scenario, tables), path)


def _read_csv(path: Path, **options: object) -> pd.DataFrame:
    """A CSV file of a result set (pandas.read_csv options); UserError naming the file when
    it is empty, not UTF-8 or not a CSV table."""
    try:
        return pd.read_csv(path, **options)
    except (OSError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError) as error:
        reason = error.strerror if isinstance(error, OSError) else str(error).splitlines()[0]
        raise UserError(f"{path} cannot be read as a CSV table ({reason}): move it away to "
                        "start a new result set") from None


WIDTH = 100  # characters a printed summary row takes at most


def summary_text(path: Path, scenario: Scenario, loss_set: str = "ideal") -> str:
    """A summary CSV of the scenario's loss set as a table for a terminal, each row at most
    WIDTH characters: the variant, E_drawn [J], eps and each joint's drive in short (from the
    set's drives.csv where there is one), then a line per failed design; every other column
    stays in the CSV."""
    table = pd.read_csv(path)
    drives = path.parent / "drives.csv"
    short = _short_drives(_read_csv(drives, keep_default_na=False)) if drives.exists() else {}
    rows = [(str(row.variant), f"{row.E_drawn:.4g}", f"{row.eps:.3g}",
             short.get(row.variant, str(getattr(row, "drive", "")))) for row in table.itertuples()]
    header = ("variant", "E_drawn [J]", "eps", "drive")
    widths = [max(len(r[i]) for r in (header, *rows)) for i in range(3)]
    room = WIDTH - sum(widths) - 6

    def line(cells: tuple[str, ...]) -> str:
        drive = cells[3] if len(cells[3]) <= room else cells[3][:room - 3] + "..."
        return (f"{cells[0]:<{widths[0]}}  {cells[1]:>{widths[1]}}  {cells[2]:>{widths[2]}}"
                f"  {drive}").rstrip()

    title = scenario.name if loss_set == "ideal" else f"{scenario.name}, {loss_set} losses"
    suffixes = {}
    for variant in scenario.variants.values():  # the joints of every variant
        resolved = scenario.for_variant(variant)
        suffixes |= {suffix(resolved, joint): joint for joint in resolved.joints}
    return "\n".join([f"{title}: every metric in {path.name}", line(header), *map(line, rows),
                      *failed_designs(table, suffixes)])


def _short_drives(drives: pd.DataFrame) -> dict[str, str]:
    """Each variant's drives in short, `joint: motor ratio:1 + screw` (the joint named where
    it has several), from a drives.csv."""
    out: dict[str, list[str]] = {}
    for variant, rows in drives.groupby("variant", sort=False):
        several = len(rows) > 1
        for row in rows.itertuples():
            ratio = f" {row.gear_ratio:g}:1" if row.gearhead else ""
            screw = f" + {row.screw}" if row.screw else ""
            out.setdefault(variant, []).append(
                f"{row.joint + ': ' if several else ''}{row.motor}{ratio}{screw}")
    return {variant: "; ".join(cells) for variant, cells in out.items()}


def failed_designs(table: pd.DataFrame, suffixes: Mapping[str, object]) -> list[str]:
    """A line per drive of the summary whose RMS current exceeds its motor's nominal
    current (drive_ok false): a failed design."""
    lines = []
    for s in suffixes:
        if f"drive_ok{s}" not in table:
            continue
        failed = table[table[f"drive_ok{s}"].astype(str) == "False"]
        lines += [f"FAILED DESIGN: {row.variant}{s and ' joint ' + s[1:]}: drive "
                  f"{row[f'drive{s}']} runs at I_rms {row[f'I_rms{s}']:.3g} A, above its "
                  f"nominal {row[f'I_nom{s}']:.3g} A" for _, row in failed.iterrows()]
    return lines
