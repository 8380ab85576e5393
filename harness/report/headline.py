"""The README's headline section (`make docs`): each study's answer and table, the one-line
answer on the papers' tasks and, per scenario and variant, E_drawn and eps with ideal and
with real parts and the drive the sizing rule gave it."""

from __future__ import annotations

import json

import pandas as pd

from harness.fmu.variable_pages import GENERATED_END
from harness.report import study
from harness.report.committed import Results, realistic
from harness.report.findings import headlines, scenario_lines
from harness.report.text import GENERATED_START, markdown_table, number, plain, wrapped


def drive_cell(results: Results, scenario: str, variant: str) -> str:
    """A variant's drives, compact: per joint its motor, gearhead ratio and the RMS current
    against the motor's nominal one, from the set's drives.csv and summary.csv."""
    drives = results.csv(f"{scenario}/drives").set_index(["variant", "joint"])
    summary = results.summary(scenario).loc[variant]
    rows = drives.loc[variant]
    several = len(rows) > 1
    cells = []
    for joint, row in rows.iterrows():
        ratio = f" {plain(row.gear_ratio)}:1" if pd.notna(row.gearhead) else " direct"
        screw = f" + {row.screw}" if pd.notna(row.screw) else ""
        current = summary[f"i_rms_{joint}" if several else "i_rms"]
        cells.append(f"{joint + ': ' if several else ''}{row.motor}{ratio}{screw} "
                     f"({number(current, 2)} / {plain(row.I_nom)} A)")
    return "; ".join(cells)


def headline_section(results: Results) -> str:
    """The README's headline: the one-line answers and, per scenario and variant, E_drawn
    and eps with ideal and with real parts, and the drive the sizing rule gave it (its RMS
    current in the realistic set against its nominal current), then the scenarios' findings
    for the README."""
    rows = []
    for name in results.scenarios():
        ideal = results.summary(name)
        real = results.summary(realistic(name)) if results.has_realistic(name) else None
        for variant, row in ideal.iterrows():
            other = real.loc[variant] if real is not None else None
            rows.append([name, f"`{variant}`", number(row.E_drawn, 4),
                         number(other.E_drawn, 4) if other is not None else "-",
                         number(row.eps, 3), number(other.eps, 3) if other is not None else "-",
                         drive_cell(results, realistic(name) if real is not None else name,
                                    variant)])
    return "\n".join(wrapped([
        "## Results at a glance", "", GENERATED_START, "", *study_lead(results),
        "### On the papers' tasks", "", *headlines(results),
        *markdown_table(["scenario", "variant", "E_drawn ideal [J]", "E_drawn realistic [J]",
                         "eps ideal", "eps realistic", "drive (I_rms / I_nom, realistic)"],
                        rows), "",
        *(line for name in results.scenarios() for line in scenario_lines(results, name, "readme")),
        GENERATED_END, ""]))


def study_lead(results: Results) -> list[str]:
    """The headline's lead: each study's answer, then its table (none without a study)."""
    names = results.studies()
    if not names:
        return []
    header, rows = study.table(names, results.csv)
    return ["### Over random tasks", "",
            "Which balancer draws the least over the tasks a machine does: every variant ran "
            "the same random tasks (moves, holds and payload changes drawn from each "
            "scenario's task model) with its own drives, sized by one rule from catalogue "
            "parts, with ideal and with real parts; intervals are 95 % bootstrap intervals "
            f"over the tasks. {study_step_error(results, names)}", "",
            *[line for name in names for line in (
                study.scenario_sentence(name, results.csv), "")],
            *markdown_table(header, rows), ""]


def study_step_error(results: Results, names: list[str]) -> str:
    """The studies' steps and the largest error each study's own step leaves in a run's
    E_drawn per loss set, against the finest step (`bench/study_step.csv`, where `make
    bench` wrote it)."""
    steps = {name: json.loads((results.folder / "study" / name / "settings.json").read_text())
             ["step"] for name in names}
    took = ("The runs take steps of "
            + ", ".join(f"{plain(1e3 * step)} ms ({name})" for name, step in steps.items()))
    link = "([docs/study.md](docs/study.md#the-step-and-its-error))"
    if not (results.folder / "bench" / "study_step.csv").is_file():
        return f"{took}; `make bench` measures the error they leave {link}."
    table = results.csv("bench/study_step")
    own = table[[steps.get(name) == step for name, step in zip(table.scenario,
                                                                    table.step_size)]]
    worst = own.groupby("losses").rel_error.max()
    return (f"{took}, which leave a run's E_drawn within "
            + " and ".join(f"{number(error, 2)} ({loss_set} set)"
                           for loss_set, error in worst.items())
            + f" of its value at {plain(1e3 * table.step_size.min())} ms {link}.")
