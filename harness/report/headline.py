"""The README's headline section (`make docs`): the one-line answers on the papers' tasks,
then one table, a row per scenario: the variant that draws the least over the study's random
tasks with real parts, its lead over the runner-up, and the variant that draws the least on
the paper's task. Every variant's figures are in docs/findings.md."""

from __future__ import annotations

from harness.fmu.variable_pages import GENERATED_END
from harness.report import study
from harness.report.committed import Results, realistic
from harness.report.findings import headlines
from harness.report.text import GENERATED_START, markdown_table, number, percent, wrapped

HEADER = ["scenario", "least E_drawn over random tasks, real parts (median, share of tasks)",
          "ahead of the runner-up, per task [J] (95 % CI)",
          "least E_drawn on the paper's task, real parts [J] (eps)"]


def random_tasks_cells(results: Results, name: str) -> list[str]:
    """A scenario's study answer in two cells: its leader with real parts (the ideal set
    without a realistic one), and its mean paired lead over the runner-up."""
    if name not in results.studies():
        return ["no study", "-"]
    summary, paired = results.csv(f"study/{name}/summary"), results.csv(f"study/{name}/paired")
    loss_set = "realistic" if "realistic" in set(summary.losses) else "ideal"
    best, second = study.ranked(summary, loss_set)[:2]
    rows = summary[summary.losses == loss_set].set_index("variant")
    gap = study.pair(paired, loss_set, best, second)
    firm = "" if gap.firm else ", not firm"
    tasks = len(results.csv(f"study/{name}/tasks"))
    return [f"`{best}`: {number(rows.E_drawn_median[best], 3)} J, "
            f"{percent(rows.least_fraction[best], 2)} % of {tasks}",
            f"{number(-gap.mean_difference, 3)} ({number(-gap.ci_high, 3)} to "
            f"{number(-gap.ci_low, 3)}) ahead of `{second}`{firm}"]


def paper_cell(results: Results, name: str) -> str:
    """The variant that draws the least on the scenario's own task with real parts (the
    ideal set without a realistic one): its E_drawn and eps."""
    table = results.summary(realistic(name) if results.has_realistic(name) else name)
    best = table.E_drawn.idxmin()
    return f"`{best}`: {number(table.E_drawn[best], 3)} ({number(table.eps[best], 3)})"


def headline_section(results: Results) -> str:
    """The README's headline (module docstring)."""
    rows = [[name, *random_tasks_cells(results, name), paper_cell(results, name)]
            for name in results.scenarios()]
    return "\n".join(wrapped([
        "## What it answers", "", GENERATED_START, "", *headlines(results),
        *markdown_table(HEADER, rows), "",
        "Every variant in both loss sets, the study's intervals and the sentences behind "
        "them: [docs/findings.md](docs/findings.md).", "", GENERATED_END, ""]))
