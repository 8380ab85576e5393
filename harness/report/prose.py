"""The findings files (docs/findings_files.md): what the pages say of a shipped scenario's
or sweep's results beyond their tables, kept beside the data they describe and filled from
the result tables by the template language (`harness.report.template`).

`harness/scenarios/findings/<scenario>.toml` and `harness/sweeps/findings/<sweep>.toml`
hold `order` (their place among the others; without it a file follows those that have one,
by name), `[values]` (names, each an expression or a plain TOML value, evaluated in order as
a text reads them) and texts: a scenario's `headline`, `findings`, `accuracy` and `readme`, a
sweep's `findings`. `harness/sweeps/findings/_section.toml` holds the `lead` of the sweeps'
section. FUNCTIONS is what every file's expressions may call.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from harness import scenarios
from harness.errors import UserError
from harness.report.template import (
    Names,
    TemplateError,
    evaluate,
    fill,
    names_read,
    placeholders,
)
from harness.report.text import (
    falls_or_rises,
    markdown_table,
    more_or_less,
    number,
    percent,
    plain,
    span,
)
from harness.sweeps.definition import SWEEP_DIR

ROOT = scenarios.SCENARIO_DIR.parents[1]
SECTION = "_section"  # a findings folder's file of its section's own texts, not a sweep's
NAME = re.compile(r"[A-Za-z]\w*")


def distinct(values: Iterable[Any]) -> list[Any]:
    """The distinct values, least first."""
    return sorted(set(values))


def where(table: pd.DataFrame, **columns: Any) -> pd.DataFrame:
    """The rows of table whose columns have the values given."""
    keep = pd.Series(True, index=table.index)
    for name, value in columns.items():
        keep &= table[name] == value
    return table[keep]


def select(table: pd.DataFrame | pd.Series, **levels: Any) -> pd.DataFrame | pd.Series:
    """The part of a table (or series) indexed by several keys at the values given of some,
    indexed by the others."""
    return table.xs(tuple(levels.values()), level=list(levels))


def saving(runs: pd.DataFrame, keys: Sequence[str], variant: str, against: str) -> pd.Series:
    """1 - E_drawn(variant) / E_drawn(against) at each point of a sweep's runs, by its keys."""
    def drawn(name: str) -> pd.Series:
        return where(runs, status="ok", variant=name).set_index(list(keys)).E_drawn
    return 1 - drawn(variant) / drawn(against)


FUNCTIONS = {  # no function that calls its arguments (sorted, min and max take no key)
    "number": number, "plain": plain, "percent": percent, "span": span,
    "more_or_less": more_or_less, "falls_or_rises": falls_or_rises,
    "table": lambda header, rows: "\n".join(markdown_table(header, rows)),
    "join": lambda separator, pieces: separator.join(pieces),
    "abs": abs, "len": len, "zip": zip, "all": all,
    "min": lambda *values: min(*values), "max": lambda *values: max(*values),
    "sorted": lambda values, reverse=False: sorted(values, reverse=reverse),
    "distinct": distinct, "where": where, "select": select, "saving": saving,
    "indexed": lambda table, keys: table.set_index(list(keys)),
    "first": lambda values: values.iloc[0], "items": lambda values: list(values.items()),
    "idxmin": lambda values: values.idxmin(), "idxmax": lambda values: values.idxmax(),
}


def shown(path: Path) -> str:
    return path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else str(path)


@dataclass(frozen=True)
class Findings:
    """A findings file: its place among the others, its values and its texts."""

    path: Path
    order: float
    values: dict[str, Any]
    texts: dict[str, str]

    def with_values(self, names: Names, read: set[str]) -> Names:
        """names with the file's values that the names in read need (the values they name,
        and those these read), each evaluated in order (an expression) or taken as it is
        (another TOML value)."""
        for name, value in reversed(self.values.items()):
            if name in read and isinstance(value, str):
                read = read | names_read(value)
        for name, value in self.values.items():
            if name in names.functions or name in names.values:
                raise UserError(f"{shown(self.path)}: value {name}: the name is the page's "
                                "(a function or a table its expressions see)")
            if name in read:
                try:
                    value = evaluate(value, names) if isinstance(value, str) else value
                except TemplateError as error:
                    raise UserError(f"{shown(self.path)}: value {name}: {error}") from None
                names = names.with_values(**{name: value})
        return names

    def lines(self, key: str, names: Names) -> list[str]:
        """The lines of text `key` (none if the file has none): its blocks (split at blank
        lines), each joined into one line with its placeholders filled from names and the
        file's values, and a blank line after each."""
        if key not in self.texts:
            return []
        blocks = [" ".join(line.strip() for line in block.splitlines())
                  for block in re.split(r"\n\s*\n", self.texts[key].strip())]
        try:
            read = {name for block in blocks for start, end in placeholders(block)
                    for name in names_read(block[start + 1:end])}
            names = self.with_values(names, read)
            filled = [fill(block, names) for block in blocks]
        except TemplateError as error:
            raise UserError(f"{shown(self.path)}: {key}: {error}") from None
        return [line for text in filled for line in [*text.split("\n"), ""]]


def read(path: Path, texts: Sequence[str]) -> Findings:
    """The findings file at path, with the texts named; UserError naming the file and what
    is wrong with it."""
    data = scenarios.read_toml(path)
    unknown = sorted(set(data) - {"order", "values", *texts})
    order, values = data.get("order", math.inf), data.get("values", {})
    problems = [f"unknown key {key!r} (known: order, values, {', '.join(texts)})"
                for key in unknown]
    if isinstance(order, bool) or not isinstance(order, int | float):
        problems.append(f"order = {order!r} is not a number")
    if not isinstance(values, dict):
        problems.append("values is not a table")
    else:
        problems += [f"value {name!r}: a name is letters, digits and _, starting with a letter"
                     for name in values if not NAME.fullmatch(name)]
    problems += [f"{key} is not text" for key in texts if not isinstance(data.get(key, ""), str)]
    if problems:
        raise UserError(f"{shown(path)}: {problems[0]}")
    return Findings(path, order, values, {key: data[key] for key in texts if key in data})


@dataclass(frozen=True)
class Folder:
    """A folder of findings files, each named by what it describes, and the texts they hold."""

    path: Path
    texts: tuple[str, ...]

    def of(self, name: str) -> Findings | None:
        """The findings file of name, if there is one."""
        path = self.path / f"{name}.toml"
        return read(path, self.texts) if path.is_file() else None

    def in_order(self, names: Iterable[str]) -> list[str]:
        """names by the order of their findings files, those without one last; ties by
        name."""
        def key(name: str) -> tuple[float, str]:
            found = self.of(name)
            return (found.order if found else math.inf, name)
        return sorted(names, key=key)

    def files(self) -> list[Findings]:
        """Every findings file in the folder (but the section's own), in order."""
        names = [p.stem for p in self.path.glob("*.toml") if p.stem != SECTION]
        return [read(self.path / f"{name}.toml", self.texts) for name in self.in_order(names)]

    def section(self, texts: Sequence[str]) -> Findings:
        """The file of the section's own texts."""
        return read(self.path / f"{SECTION}.toml", texts)


SCENARIO_FINDINGS = Folder(scenarios.SCENARIO_DIR / "findings",
                           ("headline", "findings", "accuracy", "readme"))
SWEEP_FINDINGS = Folder(SWEEP_DIR / "findings", ("findings",))
