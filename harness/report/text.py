"""Numbers and Markdown as the generated pages print them: significant digits, percentages,
ranges and the words a difference takes; tables; prose wrapped for a terminal."""

from __future__ import annotations

import math
import re
import textwrap
from collections.abc import Iterable, Sequence

GENERATED_START = ("<!-- written by `make docs` from the committed results: edits here are "
                   "replaced -->")
WIDTH = 96  # the generated prose is wrapped to this many characters, for reading in a terminal
BLOCK_START = re.compile(r"([-+*>]|\d+[.)]|#+|\||=+)( |$)")  # what Markdown reads as a block


def number(value: float, digits: int = 3) -> str:
    """value to `digits` significant digits: plain from 1e-3 up (trailing zeros kept, no
    exponent), in e-notation below ("4.2e-4"); "-" for NaN."""
    if not math.isfinite(value):
        return "-"
    if value == 0:
        return "0"
    magnitude = math.floor(math.log10(abs(float(f"{value:.{digits - 1}e}"))))
    if magnitude < -3:
        mantissa, exponent = f"{value:.{digits - 1}e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    return f"{value:.{max(digits - 1 - magnitude, 0)}f}"


def plain(value: float) -> str:
    """A parameter or an axis value as given (1, 0.05, 0.406037, 90): shortest form."""
    return f"{value:g}"


def percent(fraction: float, digits: int = 3) -> str:
    """A fraction as a percentage to `digits` significant digits (without the sign %)."""
    return number(100 * fraction, digits)


def span(values: Iterable[float], digits: int = 3, scale: float = 1.0) -> str:
    """The range of values ("a-b", or "a" when they agree at the digits shown), times scale."""
    values = list(values)
    low, high = (number(scale * v, digits) for v in (min(values), max(values)))
    return low if low == high else f"{low}-{high}"


def more_or_less(delta: float, unit: str, digits: int = 3) -> str:
    """A difference as "<|delta|> <unit> more" or "... less"."""
    return f"{number(abs(delta), digits)} {unit} {'more' if delta >= 0 else 'less'}"


def falls_or_rises(before: float, after: float, digits: int = 3) -> str:
    """"falls from a to b", "rises from a to b" or "stays at a" (at the digits shown)."""
    a, b = number(before, digits), number(after, digits)
    if a == b:
        return f"stays at {a}"
    return f"{'falls' if after < before else 'rises'} from {a} to {b}"


def wrapped(lines: Iterable[str]) -> list[str]:
    """Lines of Markdown with each paragraph line wrapped to WIDTH (headings, tables, comments
    and code kept as they are). A piece that would start a line as Markdown starts a list, a
    heading, a quote or a table stays at the end of the line before."""
    out = []
    for line in lines:
        if not line or line.startswith(("#", "|", "<!--", "    ")):
            out.append(line)
            continue
        pieces = textwrap.wrap(line, WIDTH, break_long_words=False, break_on_hyphens=False)
        out.append(pieces[0])
        for piece in pieces[1:]:
            if BLOCK_START.match(piece):
                out[-1] += " " + piece
            else:
                out.append(piece)
    return out


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """A Markdown table's lines (cells as given; '|' escaped)."""
    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"
    return [line(header), line(["---"] * len(header)), *(line(row) for row in rows)]
