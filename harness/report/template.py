"""The findings files' template language (docs/findings_files.md): text with placeholders
`{expression}` and named values, each expression filled from the tables it is given.

An expression is Python of a small kind, checked with `ast` before it runs: constants; the
names it is given (tables, rows, values, functions) and those its comprehensions bind;
attribute reads and subscripts (a column, a variant in a column, a row's field), no name
starting with `_`; `+ - * /`, comparisons, `and`/`or`/`not`, `a if c else b`; tuples and
lists, list comprehensions and generator expressions; f-strings without format specs; and
calls, by name, of the functions it is given. Anything else is refused: a method call, a
lambda, a dict, `**`, an import. What a placeholder gives, and each value an f-string
formats, is text or an integer: numbers go through the formatting functions (number,
percent, ...), which say how many digits a sentence shows.
"""

from __future__ import annotations

import ast
import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

TEXT = "_text"  # the check of an f-string's values, added to an expression after its own check
ALLOWED = (
    ast.Expression, ast.Constant, ast.Name, ast.Load, ast.Store, ast.Attribute, ast.Subscript,
    ast.Slice, ast.Tuple, ast.List, ast.BinOp, ast.Add, ast.Sub, ast.Mult, ast.Div,
    ast.UnaryOp, ast.USub, ast.UAdd, ast.Not, ast.BoolOp, ast.And, ast.Or, ast.Compare,
    ast.Eq, ast.NotEq, ast.Lt, ast.LtE, ast.Gt, ast.GtE, ast.In, ast.NotIn, ast.IfExp,
    ast.Call, ast.keyword, ast.ListComp, ast.GeneratorExp, ast.comprehension, ast.JoinedStr,
    ast.FormattedValue)
CONSTANTS = (str, int, float, bool, type(None))


class TemplateError(ValueError):
    """An expression that cannot be filled in: the expression and why, on one line."""


def refusal(expression: str, problem: str) -> TemplateError:
    """The TemplateError of an expression: `{expression}: problem`, on one line."""
    return TemplateError(" ".join(f"{{{expression}}}: {problem}".split()))


@dataclass(frozen=True)
class Names:
    """What expressions see: the functions they may call and the values they may read."""

    functions: Mapping[str, Callable[..., Any]]
    values: Mapping[str, Any]

    def with_values(self, **values: Any) -> Names:
        return Names(self.functions, {**self.values, **values})


def problem(tree: ast.Expression, names: Names) -> str | None:
    """What the parsed expression does that the language does not allow, or None."""
    bound = {node.id for node in ast.walk(tree)
             if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store)}
    known = {*names.functions, *names.values, *bound}
    nodes = list(ast.walk(tree))
    refused = next((node for node in nodes if not isinstance(node, ALLOWED)), None)
    if refused is not None:
        return f"{type(refused).__name__} is not part of the language"
    for node in nodes:
        if isinstance(node, ast.Name) and (node.id.startswith("_") or node.id not in known):
            return f"unknown name {node.id!r}"
        if isinstance(node, ast.Attribute) and node.attr.startswith("_"):
            return f"attribute {node.attr!r}: no name starting with _"
        if isinstance(node, ast.Constant) and not isinstance(node.value, CONSTANTS):
            return f"the constant {node.value!r} is not part of the language"
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name)
                                               and node.func.id in names.functions
                                               and node.func.id not in bound):
            return (f"{ast.unparse(node.func)}(...): only these functions are called: "
                    + ", ".join(sorted(names.functions)))
        if isinstance(node, ast.keyword) and node.arg is None:
            return "** is not part of the language"
        if isinstance(node, ast.FormattedValue) and (node.conversion != -1 or node.format_spec):
            return "an f-string's value takes no conversion or format spec: use number(...)"
        if isinstance(node, ast.comprehension) and node.is_async:
            return "async is not part of the language"
    return None


class _CheckFormatted(ast.NodeTransformer):
    """Each value an f-string formats goes through TEXT (text or an integer, else refused)."""

    def visit_FormattedValue(self, node: ast.FormattedValue) -> ast.FormattedValue:
        self.generic_visit(node)
        node.value = ast.Call(ast.Name(TEXT, ast.Load()), [node.value], [])
        return node


def as_text(value: Any) -> str:
    """A placeholder's value as text: text as it is, an integer in digits; TypeError for
    anything else (a float says how many digits it shows through number(...))."""
    if isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return str(value)
    raise TypeError(f"gives {type(value).__name__} {value!r}, not text: format it with "
                    "number(...), percent(...) or plain(...)")


def parsed(expression: str) -> ast.Expression:
    """The expression's tree, its lines joined into one (a value may span several lines);
    SyntaxError if it is no expression."""
    return ast.parse(" ".join(line.strip() for line in expression.splitlines()), mode="eval")


def evaluate(expression: str, names: Names) -> Any:
    """The value of an expression of the language; TemplateError saying what is wrong."""
    try:
        tree = parsed(expression)
    except SyntaxError as error:
        raise refusal(expression, f"not an expression ({error.msg})") from None
    refused = problem(tree, names)
    if refused:
        raise refusal(expression, refused)
    code = compile(ast.fix_missing_locations(_CheckFormatted().visit(tree)), "<findings>",
                   "eval")
    scope = {**names.values, **names.functions, "__builtins__": {}, TEXT: as_text}
    try:
        value = eval(code, scope)  # checked above: it calls none but the functions given
    except Exception as error:  # a missing column, variant or row, a value of another type
        raise refusal(expression, f"{type(error).__name__}: {error}") from None
    if callable(value):
        raise refusal(expression, "gives a function: call it")
    return value


def closing(text: str, start: int) -> int:
    """The index of the `}` that closes the placeholder opened at start: the first after
    which the text between is an expression (a `}` inside a string or an f-string of it
    does not close it)."""
    end = text.find("}", start)
    while end >= 0:
        try:
            parsed(text[start + 1:end])
            return end
        except SyntaxError:
            end = text.find("}", end + 1)
    raise refusal(text[start + 1:start + 40] + "...", "no } closes it as an expression")


def placeholders(text: str) -> list[tuple[int, int]]:
    """The (start, end) of each placeholder of text: the indices of its `{` and `}`."""
    found, position = [], 0
    while (start := text.find("{", position)) >= 0:
        position = closing(text, start) + 1
        found.append((start, position - 1))
    return found


def names_read(expression: str) -> set[str]:
    """The names an expression reads (none if it is no expression: evaluate says why)."""
    try:
        tree = parsed(expression)
    except SyntaxError:
        return set()
    return {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}


def fill(text: str, names: Names) -> str:
    """The text with each placeholder `{expression}` replaced by its value (text or an
    integer); TemplateError naming the first that cannot be filled."""
    pieces, position = [], 0
    for start, end in placeholders(text):
        expression = text[start + 1:end]
        value = evaluate(expression, names)
        try:
            pieces += [text[position:start], as_text(value)]
        except TypeError as error:
            raise refusal(expression, str(error)) from None
        position = end + 1
    return "".join(pieces) + text[position:]
