"""`python -m harness compare REFERENCE.csv RESULT.csv`: signal-by-signal comparison.

Both files must be regular files of at most MAX_BYTES (a FIFO, a device or a folder is
refused before anything is read), with one column per name: a name given twice, or two names
that differ only in case or surrounding blanks (`theta`, `Theta `), is refused. The result
must cover the reference's time range (to within half a sample of each end), hold every
signal of the reference (or every one named with --signals) and only finite values (no NaN,
no +-inf: one infinite reference sample would make the allowed deviation infinite) in `time`
and the compared signals; otherwise the comparison is refused with a message saying what is
missing, or naming the file, the column and the row (counted from 1 after the header) of the
first bad value.

Two checks per signal, both on the result interpolated to the reference's time points:
- tolerance: |result - reference| <= atol + rtol * max |reference| at every point;
- band: the FMI cross-check band of `fmpy.util.validate_signal` (a band around the
  reference, 20 samples wide and 10 % of the signal's range high) must hold every point.
A signal passes when both hold. The files follow the FMI cross-check CSV conventions.
"""

from __future__ import annotations

import argparse
import csv
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from fmpy.util import validate_signal

from harness.errors import UserError

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class SignalComparison:
    """Outcome for one signal: deviations in its own unit, points outside the checks."""

    name: str
    max_abs_error: float
    allowed: float
    outside_tolerance: int
    outside_band: int

    @property
    def passed(self) -> bool:
        return self.outside_tolerance == 0 and self.outside_band == 0


MAX_BYTES = 1 << 30  # a result CSV larger than 1 GiB is refused, not read


def read_result(path: Path) -> pd.DataFrame:
    """A result CSV, checked: a regular file of at most MAX_BYTES, distinct column names,
    `time` first, strictly increasing, numeric columns."""
    try:
        mode = path.stat()
    except OSError as error:
        raise UserError(f"{path}: cannot read ({error.strerror or error})") from None
    if not stat.S_ISREG(mode.st_mode):
        raise UserError(f"{path}: not a regular file (a folder, FIFO or device); give a CSV "
                        "file")
    if mode.st_size > MAX_BYTES:
        raise UserError(f"{path}: {mode.st_size:,} bytes, more than the {MAX_BYTES:,} a "
                        "result file may have")
    try:
        with path.open(newline="", encoding="utf-8") as f:
            header = next(csv.reader(f), [])
        frame = pd.read_csv(path)
    except (OSError, UnicodeDecodeError, csv.Error, pd.errors.ParserError,
            pd.errors.EmptyDataError) as error:
        raise UserError(f"{path}: cannot read as CSV ({error})") from None
    _check_names(header, path)
    if frame.columns.empty or frame.columns[0] != "time":
        raise UserError(f"{path}: the first column must be 'time'")
    if len(frame) < 2:
        raise UserError(f"{path}: needs at least two rows")
    bad = [c for c in frame.columns if not pd.api.types.is_numeric_dtype(frame[c])]
    if bad:
        raise UserError(f"{path}: non-numeric column(s) {', '.join(bad)}")
    _check_finite(frame, ["time"], str(path))
    if not np.all(np.diff(frame.time.to_numpy()) > 0):
        raise UserError(f"{path}: time is not strictly increasing")
    return frame


def _check_names(header: list[str], path: Path) -> None:
    """UserError naming the columns whose names are equal once blanks around them and case
    are ignored (pandas would read a second `theta` as `theta.1`)."""
    seen: dict[str, str] = {}
    for name in header:
        key = name.strip().casefold()
        if key in seen:
            raise UserError(f"{path}: columns {seen[key]!r} and {name!r} name one signal "
                            "(equal but for case or blanks); give each signal once")
        seen[key] = name


def _check_finite(frame: pd.DataFrame, columns: list[str], source: str) -> None:
    """UserError naming source, the columns and the first row holding NaN or +-inf."""
    values = frame[columns].to_numpy(float)
    bad = ~np.isfinite(values)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        named = [c for c, hit in zip(columns, bad.any(axis=0), strict=True) if hit]
        kinds = sorted({"NaN" if np.isnan(v) else f"{v:+g}" for v in values[bad]})
        raise UserError(f"{source} has {' and '.join(kinds)} in signal(s) "
                        f"{', '.join(named)}, first {columns[column]} = "
                        f"{values[row, column]:g} at row {row + 1}: "
                        "every compared value must be finite")


def compare(reference: pd.DataFrame, result: pd.DataFrame, signals: list[str] | None = None,
            rtol: float = 1e-3, atol: float = 1e-9,
            sources: tuple[str, str] = ("the reference", "the result")
            ) -> list[SignalComparison]:
    """Compare the named signals (default: every signal of the reference, which the result
    must all have); sources name the two tables in messages (their files)."""
    if not (rtol >= 0 and atol >= 0):
        raise UserError(f"rtol = {rtol} and atol = {atol} must be in [0, inf)")
    shared = [c for c in reference.columns[1:] if c in result.columns]
    if not shared:
        raise UserError(f"no signal in common: the reference has {', '.join(reference.columns[1:])}"
                        f"; the result has {', '.join(result.columns[1:])}")
    if signals is None:
        missing = [c for c in reference.columns[1:] if c not in result.columns]
        if missing:
            raise UserError(f"{sources[1]} lacks the reference's signal(s) "
                            f"{', '.join(missing)}; compare a subset with --signals")
        signals = shared
    unknown = [s for s in signals if s not in shared]
    if unknown:
        raise UserError(f"unknown signal(s) {', '.join(unknown)}; shared signals: "
                        f"{', '.join(shared)}")
    t_ref, t_res = reference.time.to_numpy(float), result.time.to_numpy(float)
    _check_coverage(t_ref, t_res)
    for source, table in zip(sources, (reference, result), strict=True):
        _check_finite(table, signals, source)
    inside = (t_ref >= t_res[0]) & (t_ref <= t_res[-1])
    out = []
    for name in signals:
        y_ref = reference[name].to_numpy(float)
        y_res = np.interp(t_ref[inside], t_res, result[name].to_numpy(float))
        error = np.abs(y_res - y_ref[inside])
        allowed = atol + rtol * float(np.max(np.abs(y_ref)))
        _, _, _, band_out = validate_signal(t=t_res, y=result[name].to_numpy(float),
                                            t_ref=t_ref.copy(), y_ref=y_ref)
        out.append(SignalComparison(name, float(np.max(error, initial=0.0)), allowed,
                                    int(np.sum(error > allowed)), int(np.sum(band_out))))
    return out


def _check_coverage(t_ref: np.ndarray, t_res: np.ndarray) -> None:
    """UserError unless the result spans the reference's time range, to within half of the
    reference's sample interval at each end (its own sampling may differ)."""
    slack = 0.5 * float(np.min(np.diff(t_ref)))
    if t_res[0] > t_ref[0] + slack or t_res[-1] < t_ref[-1] - slack:
        raise UserError(f"the result covers time [{t_res[0]:g}, {t_res[-1]:g}] s, not the "
                        f"reference's [{t_ref[0]:g}, {t_ref[-1]:g}] s")


def report(comparisons: list[SignalComparison]) -> str:
    """A table of the comparisons."""
    table = pd.DataFrame([{"signal": c.name, "max_abs_error": c.max_abs_error,
                           "allowed": c.allowed, "outside_tol": c.outside_tolerance,
                           "outside_band": c.outside_band,
                           "status": "ok" if c.passed else "FAIL"} for c in comparisons])
    return table.to_string(index=False, float_format=lambda v: f"{v:.4g}")


def figure(reference: pd.DataFrame, result: pd.DataFrame,
           comparisons: list[SignalComparison]) -> Figure:
    """Per signal (a row): reference, result and tolerance band (left), result - reference
    at the reference's times and the tolerance (right), each axis in the signal's unit
    (`harness.run.plots.column_unit`), the legend under the panels."""
    from matplotlib.figure import Figure  # imported here: only a plot needs it
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from harness.run.plots import column_unit, fit_suptitle

    fig = Figure(figsize=(12, 1.4 + 2.4 * len(comparisons)), layout="constrained")
    axes = fig.subplots(len(comparisons), 2, sharex=True, squeeze=False)
    t_ref = reference.time.to_numpy(float)
    for (value, difference), c in zip(axes, comparisons, strict=True):
        unit = column_unit(c.name) or "unit unknown"
        colour = "C0" if c.passed else "C3"
        y_ref = reference[c.name].to_numpy(float)
        value.fill_between(t_ref, y_ref - c.allowed, y_ref + c.allowed, color="0.85")
        value.plot(t_ref, y_ref, "k", lw=1)
        value.plot(result.time, result[c.name], "--", color=colour, lw=1)
        deviation = np.interp(t_ref, result.time.to_numpy(float),
                              result[c.name].to_numpy(float)) - y_ref
        difference.axhspan(-c.allowed, c.allowed, color="0.85")
        difference.plot(t_ref, deviation, "--", color=colour, lw=1)
        status = "ok" if c.passed else (f"FAIL: {c.outside_tolerance} points outside the "
                                        f"tolerance, {c.outside_band} outside the band")
        value.set_title(f"{c.name}: {status}", loc="left", fontsize=10)
        difference.set_title(f"{c.name}: result - reference", loc="left", fontsize=10)
        value.set_ylabel(f"{c.name} [{unit}]")
        difference.set_ylabel(f"difference [{unit}]")
        for ax in (value, difference):
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    fig.legend(handles=[Line2D([], [], color="k", lw=1, label="reference"),
                        Line2D([], [], color="C0", ls="--", lw=1, label="result (passes)"),
                        Line2D([], [], color="C3", ls="--", lw=1, label="result (fails)"),
                        Patch(color="0.85", label="tolerance: atol + rtol max|reference|")],
               loc="outside lower center", ncols=4, fontsize=8)
    passed = sum(c.passed for c in comparisons)
    fit_suptitle(fig, f"result against reference: {passed} of {len(comparisons)} signals "
                      "within tolerance")
    return fig


def plot(reference: pd.DataFrame, result: pd.DataFrame, comparisons: list[SignalComparison],
         path: Path) -> Path:
    """The comparison's `figure`, written atomically as PNG at path."""
    from harness.io import save_figure

    return save_figure(figure(reference, result, comparisons), path)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("reference", type=Path, help="reference CSV (time first)")
    parser.add_argument("result", type=Path, help="result CSV to check")
    parser.add_argument("--signals", help="comma-separated signal names (default: all shared)")
    parser.add_argument("--rtol", type=float, default=1e-3,
                        help="relative tolerance, of the signal's largest |value|")
    parser.add_argument("--atol", type=float, default=1e-9, help="absolute tolerance")
    parser.add_argument("--plot", type=Path, help="write a report plot (PNG) here (default: none)")


def run(args: argparse.Namespace) -> int:
    reference, result = read_result(args.reference), read_result(args.result)
    signals = args.signals.split(",") if args.signals else None
    comparisons = compare(reference, result, signals, args.rtol, args.atol,
                          (f"reference {args.reference}", f"result {args.result}"))
    print(report(comparisons))
    if args.plot:
        print(plot(reference, result, comparisons, args.plot))
    failed = [c.name for c in comparisons if not c.passed]
    if failed:
        print(f"{len(failed)} signal(s) outside tolerance: {', '.join(failed)}")
    return 1 if failed else 0
