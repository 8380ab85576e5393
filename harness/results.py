"""Result files (SPEC.md section 9): per-variant CSV series, a summary table, plots.

CSVs follow the FMI cross-check conventions (as fmpy.util.write_csv): quoted header,
`time` first, one column per quantity named after the FMU variable or drive signal, SI units,
booleans as 0/1. Every file is written to a temporary file in the target folder and renamed
over the old one, so a crash never leaves a half-written result.
"""

from __future__ import annotations

import csv
import os
import tempfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from harness.master import RunResult  # noqa: E402
from harness.metrics import METRICS, efficaciousness  # noqa: E402

RESULTS_DIR = Path(__file__).resolve().parent.parent / "results"
SUMMARY_COLUMNS = ("variant", *METRICS, "W_phases", "eps_W", "model", "step_size")


def write_atomic(path: Path, write: Callable[[Path], None]) -> Path:
    """Call write(temporary path) in path's folder, then rename the file onto path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        write(Path(tmp))
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; results are meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_csv(frame: pd.DataFrame, path: Path) -> Path:
    """Write a table with a quoted header and full-precision numbers, atomically."""
    def write(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            csv.writer(f, quoting=csv.QUOTE_ALL).writerow(frame.columns)
            frame.to_csv(f, header=False, index=False, float_format="%.10g")
    return write_atomic(path, write)


def summary(results: Iterable[RunResult], baseline: str | Mapping[str, str]) -> pd.DataFrame:
    """One row per variant with the metrics of SPEC section 7 and the per-phase work.

    W_phases [J] is the sum over the task's phases of |net mechanical work of the drive on the
    link in the phase|: the paper's stroke energy |integral of M dphi| summed over strokes.
    eps (on E_drawn, SPEC section 7) and eps_W (on W_phases) are computed against the
    baseline: one variant name, or a baseline per variant (Scenario.baselines); NaN where the
    baseline was not run.
    """
    results = list(results)
    rows = [{"variant": r.variant, **r.metrics,
             "W_phases": sum(abs(w) for w in r.phase_work.values()),
             "model": r.model, "step_size": r.step_size} for r in results]
    table = pd.DataFrame(rows)
    baselines = table.variant.map(
        (lambda _: baseline) if isinstance(baseline, str) else baseline.get)
    indexed = table.set_index("variant")
    for metric, column in (("E_drawn", "eps"), ("W_phases", "eps_W")):
        table[column] = efficaciousness(table[metric], baselines.map(indexed[metric]))
    return table[list(SUMMARY_COLUMNS)]


def write_run(results: list[RunResult], baseline: str | Mapping[str, str],
              out_dir: Path) -> list[Path]:
    """Write <variant>.csv for each run, summary.csv and the plot into out_dir."""
    written = [write_csv(r.series, out_dir / f"{r.variant}.csv") for r in results]
    written.append(write_csv(summary(results, baseline), out_dir / "summary.csv"))
    written.append(plot(results, out_dir / f"{results[0].scenario}.png"))
    return written


# ---- plots -------------------------------------------------------------------------------
MECHANISM_PANELS = (
    ("(a) link angle", "deg", [("theta", np.degrees), ("theta_ref", np.degrees)]),
    ("(b) energies", "J", [("E_p", None), ("E_e", None), ("E_t", None)]),
    ("(c) slider travel and payload", "mm | kg", [("delta_b", lambda v: 1e3 * v),
                                                  ("payload", None)]),
    ("(d) spring length x, counterweight distance OB", "mm", [("x", lambda v: 1e3 * v),
                                                              ("OB", lambda v: 1e3 * v)]),
)
DRIVE_PANELS = (
    ("drive torque", "N m", "tau_drive"),
    ("motor current", "A", "i"),
    ("electrical power", "W", "P_elec"),
    ("energy drawn", "J", "E_drawn"),
)


def plot(results: list[RunResult], path: Path) -> Path:
    """Franchetti Figure 5's four panels per variant (left; a model's other quantities share
    them, e.g. Ciupitu's OB in (d)) and the drive per variant (right)."""
    fig, axes = plt.subplots(4, 2, figsize=(13, 12), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for row, (title, unit, signals) in enumerate(MECHANISM_PANELS):
        ax = axes[row, 0]
        for colour, r in zip(colours, results, strict=False):
            for style, (name, convert) in zip(("-", "--", ":"), signals, strict=False):
                if name not in r.series or (name == "theta_ref" and r is not results[0]):
                    continue
                values = r.series[name].to_numpy()
                ax.plot(r.series.time, convert(values) if convert else values, style,
                        color="k" if name == "theta_ref" else colour, lw=1.2,
                        label=f"{name} ({r.variant})" if name != "theta_ref" else "reference")
        ax.set_title(title, loc="left", fontsize=10)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
    for row, (title, unit, name) in enumerate(DRIVE_PANELS):
        ax = axes[row, 1]
        for colour, r in zip(colours, results, strict=False):
            ax.plot(r.series.time, r.series[name], color=colour, lw=1.2, label=r.variant)
        ax.set_title(title, loc="left", fontsize=10)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    fig.suptitle(f"{results[0].scenario}: mechanism (panels of Franchetti et al. 2021, Fig. 5) "
                 "and drive")
    fig.tight_layout()
    return save_figure(fig, path)


def save_figure(fig: plt.Figure, path: Path) -> Path:
    """Write a figure as PNG atomically and close it."""
    def write(tmp: Path) -> None:
        fig.savefig(tmp, dpi=110, format="png")
    write_atomic(path, write)
    plt.close(fig)
    return path


def summary_text(path: Path) -> str:
    """A summary CSV as a readable table: energies in J, torque in N m, errors in deg."""
    table = pd.read_csv(path)
    for column in ("track_err_max", "track_err_rms"):
        table[column] = np.degrees(table[column])
    shown = ["variant", "E_drawn", "E_in", "E_copper", "E_mech", "tau_peak", "tau_rms",
             "i_rms", "track_err_max", "track_err_rms", "eps", "W_phases", "eps_W"]
    return (f"{path.parent.name} (tracking errors in deg)\n"
            + table[shown].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
