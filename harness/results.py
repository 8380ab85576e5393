"""Result files (docs/results.md): per-variant CSV series, a summary table, plots.

CSVs follow the FMI cross-check conventions (as fmpy.util.write_csv): quoted header,
`time` first, one column per quantity named after the FMU variable or drive signal, SI units,
booleans as 0/1. Every file is written atomically (harness.io), so a crash never leaves a
half-written result.

A scenario's folder is one result set: `write_run` merges the variants just run into it
(their CSVs replaced, the other variants' rows and curves kept), makes every file in a
staging folder first and then renames them into place in one burst, summary last, and holds
an exclusive lock on the folder meanwhile, so concurrent runs into one folder are serialised
instead of overwriting each other's rows.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from harness import registry  # noqa: E402
from harness.errors import UserError  # noqa: E402
from harness.io import save_figure, write_csv  # noqa: E402
from harness.master import RunResult, suffix  # noqa: E402
from harness.metrics import METRICS, efficaciousness  # noqa: E402
from harness.scenarios import Scenario  # noqa: E402

RESULTS_DIR = Path(__file__).resolve().parent.parent / "results"
SUMMARY_COLUMNS = ("variant", *METRICS, "W_phases", "eps_W", "model", "step_size")
# mechanism outputs a summary reports at the end of the run, where a variant's model has them
# (NaN, an empty cell, for the others): W_adjust, the cumulative work of an adjusting actuator
SUMMARY_OUTPUTS = ("W_adjust",)


def summary_columns(results: list[RunResult]) -> list[str]:
    """Columns of a summary: SUMMARY_COLUMNS for one-joint runs; with several joints the
    totals, then each drive's metrics (see harness.metrics), then eps and the rest. Where the
    runs differ in their joints, every metric any of them has, in order of appearance; the
    SUMMARY_OUTPUTS any of them has go before model."""
    metrics = dict.fromkeys(name for r in results for name in r.metrics)
    outputs = [name for name in SUMMARY_OUTPUTS if any(name in r.series for r in results)]
    return ["variant", *metrics, "eps", "W_phases", "eps_W", *outputs, "model", "step_size"]


def _summary_row(run: RunResult, per_joint: bool) -> dict[str, object]:
    """A run's metrics, its SUMMARY_OUTPUTS at the end and, with per_joint, a one-joint run's
    drive metrics also under the joint-suffixed names of several-joint runs."""
    (joint, *others) = run.joint_phase_work or [None]
    suffixed = ({f"{name}_{joint}": value for name, value in run.metrics.items()}
                if per_joint and joint is not None and not others else {})
    return {**run.metrics, **suffixed,
            **{name: float(run.series[name].iloc[-1]) for name in SUMMARY_OUTPUTS
               if name in run.series}}


def summary(results: Iterable[RunResult], baseline: str | Mapping[str, str]) -> pd.DataFrame:
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
    """
    results = list(results)
    per_joint = any(len(r.joint_phase_work) > 1 for r in results)
    rows = [{"variant": r.variant, **_summary_row(r, per_joint),
             "W_phases": sum(abs(w) for works in r.joint_phase_work.values()
                             for w in works.values()),
             "model": r.model, "step_size": r.step_size} for r in results]
    return with_eps(pd.DataFrame(rows), baseline)[summary_columns(results)]


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


@contextlib.contextmanager
def locked(out_dir: Path) -> Iterator[None]:
    """Hold an exclusive lock on the folder (flock on the folder itself, so no lock file is
    left behind and a killed writer releases it): concurrent writers wait their turn."""
    out_dir.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # not POSIX: no serialisation of concurrent writers
        yield
        return
    fd = os.open(out_dir, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def write_run(results: list[RunResult], scenario: Scenario, out_dir: Path) -> list[Path]:
    """Write <variant>.csv for each run, then the plot and summary.csv of the whole result set
    in out_dir: variants run before (with a summary row and a CSV there) are kept, eps is
    recomputed over all rows. A failure before the renames leaves the old set untouched;
    the summary is renamed last: it lists what the set holds."""
    with locked(out_dir), tempfile.TemporaryDirectory(dir=out_dir, prefix=".staging.") as tmp:
        staging = Path(tmp)  # every file is made here first, then renamed in one burst
        staged = [write_csv(r.series, staging / f"{r.variant}.csv") for r in results]
        table = summary(results, scenario.baselines)
        earlier = _earlier_runs(out_dir, scenario, table.columns, set(table.variant))
        order = list(scenario.variants)
        table = pd.concat([table, *(row for _, row in earlier)], ignore_index=True)
        table = table.sort_values("variant", key=lambda v: v.map(order.index), kind="stable")
        table = with_eps(table.reset_index(drop=True), scenario.baselines)
        runs: list[RunResult | StoredRun] = [*results, *(run for run, _ in earlier)]
        runs.sort(key=lambda r: order.index(r.variant))
        staged.append(plot(runs, scenario, staging / f"{scenario.name}.png"))
        staged.append(write_csv(table, staging / "summary.csv"))
        written = [path.replace(out_dir / path.name) for path in staged]
    return written


def _earlier_runs(out_dir: Path, scenario: Scenario, columns: pd.Index, replaced: set[str]
                  ) -> list[tuple[StoredRun, pd.DataFrame]]:
    """The variants of an existing summary that this write keeps: in the scenario, not run
    now, with the same summary columns and their series CSV present."""
    path = out_dir / "summary.csv"
    if not path.exists():
        return []
    old = pd.read_csv(path)
    if list(old.columns) != list(columns):
        return []  # another layout (an older version, or other joints): not mergeable
    kept = []
    for _, row in old.iterrows():
        series = out_dir / f"{row.variant}.csv"
        if row.variant in replaced or row.variant not in scenario.variants or not series.exists():
            continue
        kept.append((StoredRun(row.variant, row.model, pd.read_csv(series)),
                     row.to_frame().T.astype(old.dtypes.to_dict())))
    return kept


# ---- plots -------------------------------------------------------------------------------
def _to_mm(values: np.ndarray) -> np.ndarray:
    return 1e3 * values


# panels: (title, unit, [(column, conversion or None), ...]); a column ending in _ref is the
# reference, drawn once in black
MECHANISM_PANELS = (
    ("(a) link angle", "deg", [("theta", np.degrees), ("theta_ref", np.degrees)]),
    ("(b) energies", "J", [("E_p", None), ("E_e", None), ("E_t", None)]),
    ("(c) slider travel, carriage travel and payload", "mm | kg",
     [("delta_b", _to_mm), ("payload", None), ("q", _to_mm)]),
    ("(d) spring length x (l_s), counterweight distance OB or height Y_cw", "mm",
     [("x", _to_mm), ("OB", _to_mm), ("Y_cw", _to_mm), ("l_s", _to_mm)]),
)
DRIVE_PANELS = (
    ("drive torque", "N m", "tau_drive"),
    ("motor current", "A", "i"),
    ("electrical power", "W", "P_elec"),
    ("energy drawn", "J", "E_drawn"),
)
STYLES = ("-", "--", ":", "-.")


def panels(scenario: Scenario, model: str) -> tuple[tuple, tuple]:
    """(mechanism panels, drive panels) of a scenario's plot: Franchetti Figure 5's four
    panels for one-joint scenarios; per joint tracking, the model's own panels (its
    registration's plot_panels) and per drive efforts, total power and energy drawn for
    several joints."""
    if len(scenario.joints) == 1:
        return MECHANISM_PANELS, DRIVE_PANELS
    tracking, efforts = [], []
    for joint in scenario.joints:
        revolute = joint.kind == "revolute"
        convert, unit = (np.degrees, "deg") if revolute else (_to_mm, "mm")
        tracking.append((f"joint {joint.name}", unit, [(joint.position, convert),
                                                       (f"{joint.position}_ref", convert)]))
        efforts.append((f"drive effort {joint.effort} ({joint.motor} motor)",
                        "N m" if revolute else "N", joint.effort))
    found = registry.registration(model)
    own = () if found is None else tuple((title, unit, [(name, None) for name in names])
                                         for title, unit, names in found.plot_panels)
    return ((*tracking, *own),
            (*efforts, ("electrical power, all drives", "W", "P_elec"),
             ("energy drawn, all drives", "J", "E_drawn")))


def plot(results: Sequence[RunResult | StoredRun], scenario: Scenario, path: Path) -> Path:
    """The mechanism per variant (left; a model's other quantities share a panel, e.g.
    Ciupitu's OB in Franchetti's (d)) and the drives per variant (right), see `panels`."""
    mechanism, drives = panels(scenario, results[0].model)
    rows = max(len(mechanism), len(drives))
    fig, axes = plt.subplots(rows, 2, figsize=(13, 3 * rows), sharex=True, squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for row, (title, unit, signals) in enumerate(mechanism):
        ax = axes[row, 0]
        for colour, r in zip(colours, results, strict=False):
            for style, (name, convert) in zip(STYLES, signals, strict=False):
                reference = name.endswith("_ref")
                if name not in r.series or (reference and r is not results[0]):
                    continue
                values = r.series[name].to_numpy()
                ax.plot(r.series.time, convert(values) if convert else values, style,
                        color="k" if reference else colour, lw=1.2)
        # one legend entry per signal shown (line style) and per variant (colour)
        shown = [(style, name) for style, (name, _) in zip(STYLES, signals, strict=False)
                 if any(name in r.series for r in results)]
        handles = [Line2D([], [], ls=style, color="0.4", label=name)
                   for style, name in shown if not name.endswith("_ref")]
        handles += [Line2D([], [], color=colour, label=r.variant)
                    for colour, r in zip(colours, results, strict=False)
                    if any(name in r.series for _, name in shown)]
        handles += [Line2D([], [], ls=style, color="k", label="reference")
                    for style, name in shown if name.endswith("_ref")]
        ax.legend(handles=handles, fontsize=7, ncol=2)
        _decorate(ax, title, unit)
    for row, (title, unit, name) in enumerate(drives):
        ax = axes[row, 1]
        for colour, r in zip(colours, results, strict=False):
            # a several-joint run shows its first joint's signal (<name>_<joint>)
            column = name if name in r.series else next(
                c for c in r.series.columns if c.startswith(f"{name}_"))
            ax.plot(r.series.time, r.series[column], color=colour, lw=1.2, label=r.variant)
        ax.legend(fontsize=7)
        _decorate(ax, title, unit)
    for ax in axes[rows - 1:, :].ravel():
        ax.set_xlabel("time [s]")
    for row in range(len(mechanism), rows):
        axes[row, 0].set_visible(False)
    for row in range(len(drives), rows):
        axes[row, 1].set_visible(False)
    fig.suptitle(f"{scenario.name}: mechanism (panels of Franchetti et al. 2021, Fig. 5) "
                 "and drive" if len(scenario.joints) == 1 else
                 f"{scenario.name}: joints, mechanism and drives")
    fig.tight_layout()
    return save_figure(fig, path)


def _decorate(ax: plt.Axes, title: str, unit: str) -> None:
    ax.set_title(title, loc="left", fontsize=10)
    ax.set_ylabel(unit)
    ax.grid(alpha=0.3)


def summary_text(path: Path, scenario: Scenario) -> str:
    """A summary CSV as a readable table: energies in J, efforts in N m or N, tracking errors
    in deg (revolute joints) or mm (prismatic joints)."""
    table = pd.read_csv(path)
    shown = ["variant", "E_drawn", "E_in", "E_copper", "E_mech"]
    per_drive = ["tau_peak", "tau_rms", "F_peak", "F_rms", "i_rms", "V_peak", "track_err_max",
                 "track_err_rms"]
    suffixes = {}
    for variant in scenario.variants.values():  # the joints of every variant
        resolved = scenario.for_variant(variant)
        suffixes |= {suffix(resolved, joint): joint for joint in resolved.joints}
    shown += [f"{metric}{s}" for s in suffixes for metric in per_drive
              if f"{metric}{s}" in table]
    for s, joint in suffixes.items():
        for column in (f"track_err_max{s}", f"track_err_rms{s}"):
            if column in table:
                table[column] = np.degrees(table[column]) if joint.kind == "revolute" else (
                    1e3 * table[column])
    shown += ["eps", "W_phases", "eps_W", *(c for c in SUMMARY_OUTPUTS if c in table)]
    return (f"{path.parent.name} (tracking errors in deg, or mm for prismatic joints)\n"
            + table[shown].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
