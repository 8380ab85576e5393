"""docs/findings.md (`make docs`): what the committed results say. Every scenario's summary,
ideal and realistic, the study over random tasks, the co-simulation's accuracy and the
sweeps, in tables and in sentences whose numbers are read from the CSV files under results/.

Nothing runs: the files are read. The tables, and the sentences made from them alone, cover
every result set results/ holds; what the page says of one scenario or sweep is the text of
its findings file (docs/findings_files.md), filled from its tables: this module names none.
"""

from __future__ import annotations

import json
import math

import pandas as pd

from harness import scenarios
from harness.report import study
from harness.report.committed import Results, realistic
from harness.report.prose import FUNCTIONS, SCENARIO_FINDINGS, SWEEP_FINDINGS
from harness.report.template import Names
from harness.report.text import markdown_table, number, plain, span, wrapped


def joints(summary: pd.DataFrame) -> list[str]:
    """The joint suffixes of a summary's per-joint columns ("" for a one-joint summary)."""
    found = [c.removeprefix("track_err_rms_") for c in summary.columns
             if c.startswith("track_err_rms_")]
    return found or [""]


def column(name: str, joint: str) -> str:
    return f"{name}_{joint}" if joint else name


def effort_column(summary: pd.DataFrame, joint: str) -> tuple[str, str, float, str]:
    """(RMS effort column, its unit, the tracking error's scale, its unit) of a joint: a torque
    in N m with the tracking error in deg, or a force in N with it in mm."""
    if column("tau_rms", joint) in summary:
        return column("tau_rms", joint), "N m", math.degrees(1.0), "deg"
    return column("F_rms", joint), "N", 1e3, "mm"


def drawn_cell(row: pd.Series, summary: pd.DataFrame) -> str:
    """E_drawn of a variant, with each drive's share where it drives several joints."""
    total = number(row.E_drawn, 4)
    shares = [(j, row[column("E_drawn", j)]) for j in joints(summary)
              if j and column("E_drawn", j) in summary
              and math.isfinite(row[column("E_drawn", j)])]
    if len(shares) < 2:
        return total
    return f"{total} ({', '.join(f'{j} {number(v, 4)}' for j, v in shares)})"


def per_joint(row: pd.Series, summary: pd.DataFrame, name: str, scale: float = 1.0,
              digits: int = 3) -> str:
    """A per-joint metric of a variant, "a / b" over the summary's joints that it drives."""
    values = [row[column(name, j)] for j in joints(summary)
              if column(name, j) in summary and math.isfinite(row[column(name, j)])]
    return " / ".join(number(scale * v, digits) for v in values) or "-"


# ---- the pages -----------------------------------------------------------------------------
def scenario_table(results: Results, scenario: str) -> list[str]:
    """Per variant: E_drawn, E_copper and eps of the ideal and (where there is one) the
    realistic set, eps_W, and per joint the RMS effort (a torque in N m or a force in N), peak
    voltage and RMS tracking error (in deg or mm)."""
    ideal = results.summary(scenario)
    real = results.summary(realistic(scenario)) if results.has_realistic(scenario) else None
    joint_names = joints(ideal)
    if len(joint_names) == 1:
        _, effort_unit, _, track_unit = effort_column(ideal, joint_names[0])
        suffix, effort_unit, track_unit = "", f" [{effort_unit}]", f" [{track_unit}]"
    else:
        suffix, effort_unit, track_unit = f" {' / '.join(joint_names)}", "", " [deg or mm]"
    both = real is not None
    header = ["variant", "E_drawn [J]", *(["E_drawn realistic [J]"] if both else []),
              "E_copper [J]", *(["E_copper realistic [J]"] if both else []),
              "eps", *(["eps realistic"] if both else []), "eps_W",
              f"RMS effort{suffix}{effort_unit}", f"V_peak{suffix} [V]",
              f"tracking RMS{suffix}{track_unit}"]
    rows = []
    for variant, row in ideal.iterrows():
        cells = [f"`{variant}`", drawn_cell(row, ideal)]
        if real is not None:
            cells.append(drawn_cell(real.loc[variant], real))
        cells.append(number(row.E_copper, 4))
        if real is not None:
            cells.append(number(real.loc[variant].E_copper, 4))
        cells.append(number(row.eps, 4))
        if real is not None:
            cells.append(number(real.loc[variant].eps, 4))
        cells.append(number(row.eps_W, 4))
        efforts, tracking = [], []
        for joint in joint_names:
            name, _, scale, _ = effort_column(ideal, joint)
            if math.isfinite(row.get(name, math.nan)):
                efforts.append(number(row[name], 3))
                tracking.append(number(scale * row[column("track_err_rms", joint)], 2))
        cells += [" / ".join(efforts) or "-", per_joint(row, ideal, "V_peak"),
                  " / ".join(tracking) or "-"]
        rows.append(cells)
    return markdown_table(header, rows)


def ranking_sentence(results: Results) -> str:
    """Whether the order of the variants by E_drawn is the same with ideal and real parts."""
    changed = [s for s in results.scenarios() if results.has_realistic(s) and list(
        results.summary(s).E_drawn.sort_values().index) != list(
        results.summary(realistic(s)).E_drawn.sort_values().index)]
    if not changed:
        return ("the order of the variants by E_drawn is the same as with ideal parts in every "
                "scenario, but the margins move")
    return (f"the order of the variants by E_drawn changes in {', '.join(changed)} and holds "
            "in the other scenarios")


def scenario_lines(results: Results, name: str, key: str) -> list[str]:
    """Text `key` of the scenario's findings file, filled from its two result sets (a blank
    line after each paragraph); none without the text or the realistic set. Its expressions
    see `ideal` and `real` (the summaries by variant), `phases` (name: (start, end) [s]),
    `parameters` (variant: its own parameters), `ranking` (whether the variants' order holds
    with real parts), `at(variant, time)` (the recorded row nearest to time [s]) and
    `csv(name)`."""
    findings = SCENARIO_FINDINGS.of(name)
    if findings is None or key not in findings.texts or not results.has_realistic(name):
        return []
    scenario = scenarios.load(name)
    values = {"ideal": results.summary(name), "real": results.summary(realistic(name)),
              "ranking": ranking_sentence(results),
              "phases": {phase: (start, end) for phase, start, end in scenario.phase_times()},
              "parameters": {v: dict(variant.parameters)
                             for v, variant in scenario.variants.items()}}
    functions = {**FUNCTIONS, "csv": results.csv,
                 "at": lambda variant, time: results.at(name, variant, time)}
    return findings.lines(key, Names(functions, values))


def sweep_lines(results: Results) -> list[str]:
    """The sweeps' section after its heading: its lead and each sweep's findings, in order.
    A sweep's expressions see `runs` (its
    results/sweeps/<sweep>.csv), `runs_note` (that file and its number of runs, and of
    failed ones) and `csv(name)`."""
    functions = {**FUNCTIONS, "csv": results.csv}
    lines = SWEEP_FINDINGS.section(("lead",)).lines("lead", Names(functions, {}))
    for findings in SWEEP_FINDINGS.files():
        name = findings.path.stem
        runs = results.csv(f"sweeps/{name}")
        failed = int((runs.status != "ok").sum())
        note = (f"`results/sweeps/{name}.csv`, {len(runs)} runs"
                + (f", {failed} failed" if failed else ""))
        names = Names(functions, {"runs": runs, "runs_note": note})
        lines += findings.lines("findings", names)
    return lines


def scenario_section(results: Results, name: str) -> list[str]:
    ideal = results.summary(name)
    scenario = scenarios.load(name) if name in scenarios.available() else None
    lines = [f"## {name}", ""]
    if scenario is not None:
        compared: dict[str, list[str]] = {}
        for variant, baseline in scenario.baselines.items():
            if variant != baseline:
                compared.setdefault(baseline, []).append(f"`{variant}`")
        lines += [f"{scenario.description} eps against "
                  + "; ".join(f"`{b}` for {', '.join(v)}" for b, v in compared.items())
                  + ".", ""]
    files = f"`results/{name}/summary.csv`" + (
        f", `results/{realistic(name)}/summary.csv`" if results.has_realistic(name) else "")
    steps = ", ".join(plain(1e3 * h) for h in ideal.step_size.unique())
    lines += [f"{files}; the plot: [`{name}.png`](../results/{name}/{name}.png). At a "
              f"communication step of {steps} ms.", ""]
    lines += scenario_table(results, name) + [""]
    return (lines + scenario_lines(results, name, "findings")
            + scenario_lines(results, name, "readme"))


def accuracy_section(results: Results) -> list[str]:
    convergence = results.csv("bench/convergence")
    worst = convergence.groupby(["scenario", "step_size"], sort=False).max_rel_err.max()
    per_scenario = []
    for scenario, errors in worst.groupby(level="scenario", sort=False):
        errors = errors.droplevel("scenario").sort_index(ascending=False)
        steps = list(errors.index)
        orders = [math.log2(errors[a] / errors[b]) for a, b in zip(steps, steps[1:])]
        variants = convergence[convergence.scenario == scenario].variant.nunique()
        per_scenario.append(
            f"{scenario} ({variants} variants) "
            + ", ".join(f"{number(errors[h], 2)} at {number(1e3 * h, 1)} ms" for h in steps)
            + f", order {span(orders, 2)}")
    lines = [
        "## Accuracy of the co-simulation", "",
        "Against the monolithic reference (`cosim --engine reference`: the whole system as one "
        "ODE in `solve_ivp`, continuous controllers; `results/bench/convergence.csv`, every "
        "variant with a reference, legacy drives), the largest relative error of an energy "
        "metric is, per scenario: " + "; ".join(per_scenario) + " in the step (first order: "
        "the one-step delay of the exchange).", ""]
    for name in results.scenarios():
        lines += scenario_lines(results, name, "accuracy")
    return lines + ecco_lines(results)


def ecco_lines(results: Results) -> list[str]:
    """ECCO's steps and E_drawn error in each case of `bench/ecco.csv` against the fixed
    steps', and what they say."""
    ecco = results.csv("bench/ecco")
    fixed = ecco[ecco.algorithm == "fixed"]
    lines = [
        "ECCO (`cosim --engine libcosim-ecco`, [results.md](results.md#variable-steps-ecco)): "
        "steps taken and the relative E_drawn error against the monolithic reference "
        "(`results/bench/ecco.csv`, `ecco.png`):", ""]
    cases = ecco.groupby(["scenario", "variant"], sort=False)
    fixed_steps = sorted(fixed.step_size.unique(), reverse=True)
    tolerances = sorted(ecco.abs_tolerance.dropna().unique(), reverse=True)
    header = ["case", *(f"fixed {number(1e3 * h, 1)} ms" for h in fixed_steps),
              *(f"ECCO {number(t, 1)} J" for t in tolerances)]
    rows, verdicts = [], []
    for (scenario, variant), case in cases:
        by_step = case[case.algorithm == "fixed"].set_index("step_size")
        by_tolerance = case[case.algorithm == "ecco"].set_index("abs_tolerance")
        rows.append([f"{scenario} {variant}",
                     *(f"{int(by_step.steps[h])}: {number(by_step.err_E_drawn[h], 3)}"
                       for h in fixed_steps),
                     *(f"{int(by_tolerance.steps[t])}: {number(by_tolerance.err_E_drawn[t], 3)}"
                       for t in tolerances)])
        target = by_step.loc[1e-3]
        better = by_tolerance[by_tolerance.err_E_drawn <= target.err_E_drawn]
        if len(better):
            best = better.loc[better.steps.idxmin()]
            verdicts.append(
                f"On {scenario} ECCO at {number(best.name, 1)} J beats the 1 ms step's E_drawn "
                f"accuracy with {number(target.steps / best.steps, 2)} times fewer steps.")
        else:
            closest = by_tolerance.loc[by_tolerance.err_E_drawn.idxmin()]
            verdicts.append(
                f"On {scenario} no tolerance reaches the 1 ms step's E_drawn accuracy "
                f"({number(target.err_E_drawn, 3)}): the closest, {number(closest.name, 1)} J, "
                f"gives {number(closest.err_E_drawn, 3)} with "
                f"{number(target.steps / closest.steps, 2)} times fewer steps, and the event "
                f"lag reaches {number(1e3 * case.event_lag_max.max(), 2)} ms (ECCO does not hit "
                "the phase starts).")
        ordered = by_tolerance.sort_index(ascending=False)
        tightest = ordered.iloc[-1]
        if tightest.err_E_drawn > ordered.err_E_drawn.min():
            falling = bool((ordered.bond_error.diff().dropna() < 0).all())
            verdicts.append(
                f"A tighter tolerance does not make E_drawn better: "
                f"{number(tightest.err_E_drawn, 3)} at {number(tightest.name, 1)} J, while the "
                "bonds' own error "
                + ("keeps falling (" if falling else "moves (")
                + ", ".join(f"{number(b, 2)} J" for b in ordered.bond_error)
                + f"; the 1 ms step's {number(target.bond_error, 2)} J).")
    return lines + markdown_table(header, rows) + ["", " ".join(verdicts), ""]


def headlines(results: Results) -> list[str]:
    """The one-line answers: each scenario's headline, a blank line after each."""
    return [line for name in results.scenarios()
            for line in scenario_lines(results, name, "headline")]


def findings_markdown(results: Results) -> str:
    """docs/findings.md."""
    lines = [
        "# Findings: what the committed results say", "",
        "Generated by `make docs` (`harness/report/`) from the CSV files under "
        "[`results/`](../results/) that `make cosim`, `make sweep` and `make bench` write; "
        "`tests/test_docs.py` fails when this page differs from what they give, so edit the "
        "findings files ([findings_files.md](findings_files.md)) or the generator, not the "
        "page. Columns and metrics: [results.md](results.md); the losses "
        "of the realistic sets: [losses.md](losses.md).", "",
        *headlines(results),
        "Every scenario runs each variant twice in the FMPy master: with the ideal parts its "
        "file describes and with the losses of real parts (\"realistic\"). eps = 1 - E_drawn / "
        "E_drawn(baseline) on the energy drawn from a supply that takes nothing back; several "
        "joints show their values as \"a / b\" in the order of the column's title.", ""]
    lines += study_section(results)
    for name in results.scenarios():
        lines += scenario_section(results, name)
    lines += [*accuracy_section(results), "## Sweeps", "", *sweep_lines(results)]
    return "\n".join(wrapped(lines)).rstrip("\n") + "\n"


def study_section(results: Results) -> list[str]:
    """docs/findings.md's study: each scenario's answer, its firm and its open comparisons
    (neighbours in the ranking), and the median ratios by quartile of the task figures."""
    names = results.studies()
    if not names:
        return []
    lines = ["## Over random tasks: the study", "",
             "From `results/study/<scenario>/` ([study.md](study.md)): per scenario, every "
             "variant over the same random tasks, in both loss sets; E_drawn medians with the "
             "5 % and 95 % quantiles over the tasks, paired differences as means over the tasks "
             "with 95 % percentile-bootstrap intervals "
             f"({int(results.csv(f'study/{names[0]}/paired').resamples.iloc[0]):,} resamples "
             "of the tasks, a fixed seed). A comparison is firm when its interval excludes 0. "
             f"{study_step_error(results, names)}", ""]
    header, rows = study.table(names, results.csv)
    lines += [*markdown_table(header, rows), ""]
    for name in names:
        lines += [f"### {name}", "",
                  study.scenario_sentence(name, results.csv), ""]
        lines += study.firmness(name, results.csv)
        header, rows = study.dependence_table(name, results.csv)
        if rows:
            lines += ["Median E_drawn over the reference variant's, by quartile of the tasks "
                      "(realistic set):", "", *markdown_table(header, rows), ""]
    return lines


def study_step_error(results: Results, names: list[str]) -> str:
    """The studies' steps and the largest error each study's own step leaves in a run's
    E_drawn per loss set, against the finest step (`bench/study_step.csv`, where `make
    bench` wrote it)."""
    steps = {name: json.loads((results.folder / "study" / name / "settings.json").read_text())
             ["step"] for name in names}
    took = ("The runs take steps of "
            + ", ".join(f"{plain(1e3 * step)} ms ({name})" for name, step in steps.items()))
    link = "([study.md](study.md#the-step-and-its-error))"
    if not (results.folder / "bench" / "study_step.csv").is_file():
        return f"{took}; `make bench` measures the error they leave {link}."
    table = results.csv("bench/study_step")
    own = table[[steps.get(name) == step for name, step in zip(table.scenario,
                                                                    table.step_size)]]
    worst = own.groupby("losses").rel_error.max()
    return (f"{took}, which leave a run's E_drawn within "
            + " and ".join(f"{number(error, 2)} ({loss_set} set)"
                           for loss_set, error in worst.items())
            + f" of its value at {plain(1e3 * table.step_size.min())} ms {link}."
)
