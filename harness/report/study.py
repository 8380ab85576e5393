"""The study's answer in words and tables, for the README's headline and docs/findings.md,
from the committed study under results/study/<scenario>/ (docs/study.md): which variant
draws the least over the random tasks, by how much, with what confidence, and where the
ranking changes with the task."""

from __future__ import annotations

from collections.abc import Callable

import pandas as pd

from harness.report.text import number, percent

SETS = ("realistic", "ideal")      # the realistic set leads: it is what a machine draws
AXIS_WORDS = {"changes_per_min": ("payload changes per minute", "/min"),
              "hold_fraction": ("fraction of the task spent holding", "")}
Csv = Callable[[str], pd.DataFrame]


def ranked(summary: pd.DataFrame, loss_set: str) -> list[str]:
    """The variants of a loss set by median E_drawn, least first."""
    rows = summary[summary.losses == loss_set]
    return list(rows.sort_values("E_drawn_median").variant)


def pair(paired: pd.DataFrame, loss_set: str, variant: str, other: str) -> pd.Series:
    rows = paired[(paired.losses == loss_set) & (paired.variant == variant)
                  & (paired.other == other)]
    return rows.iloc[0]


def interval(row: pd.Series) -> str:
    """ "a J (95 % CI b to c J)" of a paired row."""
    return (f"{number(row.mean_difference, 3)} J (95 % CI {number(row.ci_low, 3)} to "
            f"{number(row.ci_high, 3)} J)")


def less_per_task(row: pd.Series) -> str:
    """A paired row of a variant that draws less than the other, in words: "d J less per
    task (95 % CI a to b J)"."""
    return (f"{number(-row.mean_difference, 3)} J less per task (95 % CI "
            f"{number(-row.ci_high, 3)} to {number(-row.ci_low, 3)} J)")


def ranking_change(dependence: pd.DataFrame, loss_set: str) -> str:
    """Where the variant with the least median E_drawn ratio changes along each task figure,
    or that it does not."""
    parts = []
    rows = dependence[dependence.losses == loss_set]
    for axis, (words, unit) in AXIS_WORDS.items():
        along = rows[rows.axis == axis]
        if along.empty:
            continue
        bins = along.groupby(["low", "high"], sort=True)
        leaders: list[tuple[float, float, str]] = []
        for (low, high), group in bins:   # neighbouring bins with one leader merged
            leader = group.sort_values("ratio_median").variant.iloc[0]
            if leaders and leaders[-1][2] == leader:
                low = leaders.pop()[0]
            leaders.append((low, high, leader))
        names = list(dict.fromkeys(leader for _, _, leader in leaders))
        if len(names) == 1:
            parts.append(f"`{names[0]}` leads in every quartile of the {words} "
                         f"({number(leaders[0][0], 2)} to {number(leaders[-1][1], 2)}{unit})")
        else:
            spans = ", ".join(f"`{leader}` from {number(low, 2)} to {number(high, 2)}{unit}"
                              for low, high, leader in leaders)
            parts.append(f"along the {words} the leader changes: {spans}")
    return "; ".join(parts)


def scenario_sentence(name: str, csv: Csv) -> str:
    """One scenario's answer: the leader with real parts, how often it leads, by how much
    against the runner-up, and where the ranking changes."""
    summary, paired = csv(f"study/{name}/summary"), csv(f"study/{name}/paired")
    tasks = csv(f"study/{name}/tasks")
    dependence = csv(f"study/{name}/dependence")
    loss_set = "realistic" if "realistic" in set(summary.losses) else "ideal"
    order = ranked(summary, loss_set)
    best, second = order[0], order[1]
    rows = summary[summary.losses == loss_set].set_index("variant")
    gap = pair(paired, loss_set, best, second)
    figures = (f"{len(tasks)} tasks of {tasks.moves.min()} to {tasks.moves.max()} moves, "
               f"holding {percent(tasks.hold_fraction.min(), 2)} to "
               f"{percent(tasks.hold_fraction.max(), 2)} % of the time")
    if tasks.changes.max() > 0:
        figures += (f", {number(tasks.changes_per_min.min(), 2)} to "
                    f"{number(tasks.changes_per_min.max(), 2)} payload changes per minute")
    change = ranking_change(dependence, loss_set)
    return (
        f"**{name}** ({figures}): with real parts `{best}` draws the least in "
        f"{percent(rows.least_fraction[best], 2)} % of the tasks, a median "
        f"{number(rows.E_drawn_median[best], 3)} J against {number(rows.E_drawn_median[second], 3)}"
        f" J for `{second}`, the runner-up, and {less_per_task(gap)} than it "
        f"({'firm: the interval excludes 0' if gap.firm else 'not firm: the interval holds 0'})"
        "." + (f" By task: {change}." if change else ""))


def table(names: list[str], csv: Csv) -> tuple[list[str], list[list[str]]]:
    """Per scenario and variant: median E_drawn with its 5-95 % span in each set, the share
    of tasks it draws the least in, and its mean paired difference to the task model's
    reference variant with real parts."""
    header = ["scenario", "variant", "E_drawn realistic [J], median (5-95 %)",
              "E_drawn ideal [J], median (5-95 %)", "least (realistic / ideal)",
              "against the reference, realistic [J] (95 % CI)"]
    rows = []
    for name in names:
        summary, paired = csv(f"study/{name}/summary"), csv(f"study/{name}/paired")
        sets = [s for s in SETS if s in set(summary.losses)]
        reference = summary[summary.ratio_median == 1.0].variant.iloc[0]
        by_set = {s: summary[summary.losses == s].set_index("variant") for s in sets}
        for variant in by_set[sets[0]].index:
            cells = []
            for loss_set in ("realistic", "ideal"):
                if loss_set not in by_set:
                    cells.append("-")
                    continue
                r = by_set[loss_set].loc[variant]
                cells.append(f"{number(r.E_drawn_median, 3)} ({number(r.E_drawn_q05, 2)}-"
                             f"{number(r.E_drawn_q95, 2)})")
            least = " / ".join(f"{percent(by_set[s].least_fraction[variant], 2)} %"
                               for s in sets)
            row = pair(paired, sets[0], variant, reference) if variant != reference else None
            versus = "reference" if row is None else (
                f"{number(row.mean_difference, 3)} ({number(row.ci_low, 3)} to "
                f"{number(row.ci_high, 3)})")
            rows.append([name, f"`{variant}`", *cells, least, versus])
    return header, rows


def firmness(name: str, csv: Csv) -> list[str]:
    """Each loss set's ranking by median E_drawn, each neighbour's mean paired difference
    to the next, and whether it is firm."""
    summary, paired = csv(f"study/{name}/summary"), csv(f"study/{name}/paired")
    lines = []
    for loss_set in (s for s in SETS if s in set(summary.losses)):
        order = ranked(summary, loss_set)
        steps = []
        for better, worse in zip(order, order[1:]):
            row = pair(paired, loss_set, better, worse)
            verdict = "firm" if row.firm else "not firm"
            steps.append(f"`{better}` - `{worse}`: {interval(row)}, {verdict}")
        lines += [f"- {loss_set}, by median E_drawn, least first; the mean paired difference "
                  "of each to the next: " + "; ".join(steps) + "."]
    return [*lines, ""]


def dependence_table(name: str, csv: Csv) -> tuple[list[str], list[list[str]]]:
    """Per task figure and quartile of the realistic set (the ideal one if there is none):
    each variant's median ratio to the reference."""
    dependence = csv(f"study/{name}/dependence")
    if dependence.empty:
        return [], []
    loss_set = "realistic" if "realistic" in set(dependence.losses) else "ideal"
    rows = dependence[dependence.losses == loss_set]
    variants = list(dict.fromkeys(rows.variant))
    header = ["task figure", "quartile", "tasks", *[f"`{v}`" for v in variants]]
    table = []
    for (axis, low, high), group in rows.groupby(["axis", "low", "high"], sort=False):
        ratio = group.set_index("variant").ratio_median
        words, unit = AXIS_WORDS[axis]
        table.append([words, f"{number(low, 2)} to {number(high, 2)}{unit}",
                      str(int(group.tasks.iloc[0])), *[number(ratio[v], 3) for v in variants]])
    return header, table
