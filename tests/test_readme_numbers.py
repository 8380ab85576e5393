"""The README's numbers against the committed results, at the precision they are printed.

Two kinds of quoted number (README.md, "Results in brief"):
- a cell of a results table: a table that follows a paragraph naming
  `results/<scenario>/summary.csv`; its row is the variant (first cell), its column one of
  COLUMNS, which names the summary column(s) and the unit conversion. A column header the
  test does not know fails it, so a new column comes with its mapping.
- a number in prose marked `<!--= EXPRESSION -->` right after it: EXPRESSION is arithmetic
  (+ - * / and parentheses, numbers) over terms, each one cell of a committed CSV file:
  `<set>:<variant>:<column>`, a row of the summary `results/<set>/summary.csv` (e.g.
  `franchetti2021/realistic:self_regulating:E_drawn`), or `<file>[<key>=<value>,...]:<column>`,
  the one row of `results/<file>.csv` with those values (e.g.
  `sweeps/regulation[variant=self_regulating,payload=1,regulation_angle=180]:E_drawn`).

A printed number with n decimals holds when it is the value rounded to n decimals.
Nothing runs: the files are read.
"""

from __future__ import annotations

import ast
import math
import operator
import re
from collections.abc import Callable
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
RESULTS = ROOT / "results"
JOINT_SUFFIXES = ("theta", "q", "q1", "q2")


def _deg(value: float) -> float:
    return math.degrees(value)


def _mm(value: float) -> float:
    return 1e3 * value


# header -> (loss set folder, [(summary column, conversion)] for the numbers of a cell in
# order); a column given without joint suffix also matches its per-joint columns (below)
COLUMNS: dict[str, tuple[str, list[tuple[str, Callable[[float], float] | None]]]] = {
    "E_drawn [J]": ("", [("E_drawn", None)]),
    "E_drawn realistic [J]": ("realistic", [("E_drawn", None)]),
    "E_copper [J]": ("", [("E_copper", None)]),
    "eps": ("", [("eps", None)]),
    "eps realistic": ("realistic", [("eps", None)]),
    "eps_W (stroke work)": ("", [("eps_W", None)]),
    "tracking RMS [deg]": ("", [("track_err_rms", _deg)]),
    "V_peak [V]": ("", [("V_peak", None)]),
    "V_peak q1 / q2 [V]": ("", [("V_peak_q1", None), ("V_peak_q2", None)]),
    "tracking RMS q1 [deg] / q2 [mm]": ("", [("track_err_rms_q1", _deg),
                                             ("track_err_rms_q2", _mm)]),
}
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")
MARKED = re.compile(r"(-?\d+(?:\.\d+)?)<!--=(.*?)-->", re.DOTALL)
TERM = re.compile(r"([A-Za-z0-9_/]+)\[([^\]]*)\]:(\w+)|([A-Za-z0-9_/]+):(\w+):(\w+)")
OPERATORS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
             ast.Div: operator.truediv, ast.USub: operator.neg}


@cache
def summary(result_set: str) -> pd.DataFrame:
    return pd.read_csv(RESULTS / result_set / "summary.csv").set_index("variant")


def decimals(printed: str) -> int:
    return len(printed.split(".")[1]) if "." in printed else 0


def holds(printed: str, value: float) -> bool:
    """Whether printed is value rounded to its decimals (half a unit of its last digit,
    with a rounding margin for values written to 10 digits)."""
    return abs(float(printed) - value) <= 0.5 * 10.0 ** -decimals(printed) * (1 + 1e-6)


def results_tables() -> list[tuple[str, list[str], list[list[str]]]]:
    """(scenario, header, rows) of every README table after a paragraph naming a
    `results/<scenario>/summary.csv` (under the same heading)."""
    tables, scenario, lines = [], None, README.read_text().splitlines()
    index = 0
    while index < len(lines):
        line = lines[index]
        named = re.search(r"`results/([a-z0-9_]+)/summary\.csv`", line)
        if named:
            scenario = named.group(1)
        if line.startswith("|") and scenario is not None:
            block = []
            while index < len(lines) and lines[index].startswith("|"):
                block.append([cell.strip() for cell in lines[index].strip("|").split("|")])
                index += 1
            tables.append((scenario, block[0], block[2:]))
            scenario = None
            continue
        if line.startswith("#"):
            scenario = None  # a table under another heading is not that summary's
        index += 1
    return tables


def cell_columns(table: pd.DataFrame, variant: str, header: str, count: int
                 ) -> list[tuple[str, Callable[[float], float] | None]]:
    """The summary columns a cell's numbers come from: the header's, and where the cell has
    more numbers than that, the per-joint columns of the header's column (a several-joint
    variant: the total, then each joint, e.g. E_drawn (link .., anchor ..))."""
    _, columns = COLUMNS[header]
    if count == len(columns):
        if all(not pd.isna(table.at[variant, c]) for c, _ in columns):
            return columns
    (name, convert), = columns
    candidates = [name, *(f"{name}_{s}" for s in JOINT_SUFFIXES)]
    present = [c for c in candidates if c in table and not pd.isna(table.at[variant, c])]
    return [(c, convert) for c in present[:count]]


def table_cells() -> list[tuple[str, str, str, str, str, float]]:
    cells = []
    for scenario, header, rows in results_tables():
        assert header[0] == "variant", (scenario, header)
        for title in header[1:]:
            assert title in COLUMNS, f"README table of {scenario}: no mapping for {title!r}"
        for row in rows:
            variant = row[0]
            for title, text in zip(header[1:], row[1:], strict=True):
                folder, _ = COLUMNS[title]
                result_set = f"{scenario}/{folder}" if folder else scenario
                table = summary(result_set)
                numbers = NUMBER.findall(text)
                assert numbers, (scenario, variant, title, text)
                columns = cell_columns(table, variant, title, len(numbers))
                assert len(columns) == len(numbers), (scenario, variant, title, text)
                for printed, (column, convert) in zip(numbers, columns, strict=True):
                    value = float(table.at[variant, column])
                    cells.append((result_set, variant, title, column, printed,
                                  convert(value) if convert else value))
    return cells


@cache
def result_table(file: str) -> pd.DataFrame:
    return pd.read_csv(RESULTS / f"{file}.csv")


def row_value(file: str, where: str, column: str) -> float:
    """The column of the one row of results/<file>.csv whose key columns have the values of
    where (`key=value,...`; numbers compared as numbers)."""
    table = result_table(file)
    chosen = np.ones(len(table), dtype=bool)
    for condition in where.split(","):
        key, value = (part.strip() for part in condition.split("="))
        cells = table[key]
        chosen &= (np.isclose(cells.astype(float), float(value), rtol=0, atol=1e-12)
                   if pd.api.types.is_numeric_dtype(cells) else (cells.astype(str) == value))
    if chosen.sum() != 1:
        raise ValueError(f"results/{file}.csv has {chosen.sum()} rows with {where}, not one")
    return float(table.loc[chosen, column].iloc[0])


def evaluate(expression: str) -> float:
    """The value of a marker's expression (module docstring)."""
    terms = {}

    def term(match: re.Match) -> str:
        name = f"_t{len(terms)}"
        file, where, column, result_set, variant, summary_column = match.groups()
        terms[name] = (float(summary(result_set).at[variant, summary_column]) if file is None
                       else row_value(file, where, column))
        return name

    tree = ast.parse(TERM.sub(term, " ".join(expression.split())), mode="eval")

    def value(node: ast.AST) -> float:
        if isinstance(node, ast.Expression):
            return value(node.body)
        if isinstance(node, ast.BinOp) and type(node.op) in OPERATORS:
            return OPERATORS[type(node.op)](value(node.left), value(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in OPERATORS:
            return OPERATORS[type(node.op)](value(node.operand))
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id in terms:
            return terms[node.id]
        raise ValueError(f"marker {expression!r}: {ast.dump(node)} is not arithmetic over "
                         "<set>:<variant>:<column> terms")
    return value(tree)


def test_every_results_table_is_found_and_mapped() -> None:
    """The three scenarios' tables, each with realistic columns beside the ideal ones."""
    tables = results_tables()
    assert [scenario for scenario, _, _ in tables] == ["franchetti2021", "ciupitu2018",
                                                         "demian2022"]
    for scenario, header, rows in tables:
        assert {"E_drawn realistic [J]", "eps realistic"} <= set(header), scenario
        assert [row[0] for row in rows] == list(summary(scenario).index), scenario


@pytest.mark.parametrize("cell", table_cells(), ids=lambda c: f"{c[0]}.{c[1]}.{c[3]}")
def test_table_cell_is_the_committed_result(cell: tuple) -> None:
    result_set, variant, title, column, printed, value = cell
    assert holds(printed, value), (f"README {result_set} {variant} {title!r}: printed "
                                   f"{printed}, results {column} = {value}")


def marked() -> list[tuple[str, str]]:
    return MARKED.findall(README.read_text())


def test_marked_numbers_are_found() -> None:
    assert len(marked()) >= 20  # the realistic comparison's numbers at least
    text = README.read_text()
    markers = re.findall(r"(?<!`)<!--=", text)  # not those quoted in code spans
    assert len(markers) == len(marked()), "a marker not right after a number"


@pytest.mark.parametrize("printed, expression", marked(), ids=lambda v: " ".join(v.split())[:60])
def test_marked_number_is_the_committed_result(printed: str, expression: str) -> None:
    value = evaluate(expression)
    assert holds(printed, value), f"README prints {printed}, {expression.strip()} = {value}"


def test_the_claimed_ranking_holds_under_real_parts() -> None:
    """The README says the order of E_drawn is the same in every ideal and realistic table."""
    for scenario in ("franchetti2021", "ciupitu2018", "demian2022"):
        ideal, real = summary(scenario), summary(f"{scenario}/realistic")
        assert list(ideal.E_drawn.sort_values().index) == list(
            real.E_drawn.sort_values().index), scenario


def test_holds_is_the_printed_precision() -> None:
    assert holds("0.0699", 0.069907) and not holds("0.0699", 0.06996)
    assert holds("23.346", 23.345816) and not holds("23.35", 23.344)
    assert evaluate("100 * franchetti2021:unbalanced:eps + 2") == 2.0
    # a sweep's row by its parameters: the regulation sweep's 1 kg at 180 deg is the
    # committed scenario's self-regulation (the same run)
    regulated = evaluate("sweeps/regulation[variant=self_regulating, payload=1, "
                         "regulation_angle=180]:E_drawn")
    assert regulated == pytest.approx(evaluate("franchetti2021:self_regulating:E_drawn"),
                                      rel=1e-6)
    with pytest.raises(ValueError, match="rows"):
        evaluate("sweeps/regulation[variant=self_regulating]:E_drawn")
    with pytest.raises(ValueError):
        evaluate("__import__('os')")
