"""The findings files' template language (harness.report.template, docs/findings_files.md):
what it fills in, what it refuses and how it says so, and the findings files beside the
shipped scenarios and sweeps (harness.report.prose)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from harness import scenarios
from harness.errors import UserError
from harness.report.prose import FUNCTIONS, SCENARIO_FINDINGS, SWEEP_FINDINGS, Folder, read
from harness.report.template import Names, TemplateError, evaluate, fill, placeholders
from harness.sweeps.definition import SWEEP_DIR

SUMMARY = pd.DataFrame({"variant": ["a", "b"], "E_drawn": [0.5, 4.0], "eps": [0.875, 0.0]}
                       ).set_index("variant")
NAMES = Names(FUNCTIONS, {"ideal": SUMMARY, "laws": ("x", "y")})


def test_placeholders_are_filled_from_the_tables() -> None:
    """Attribute reads, subscripts, arithmetic, conditionals, comprehensions and nested
    f-strings, against numbers worked out by hand: 0.5 / 4.0 = 12.5 %."""
    text = ("a draws {percent(ideal.E_drawn.a / ideal.E_drawn['b'], 2)} % of b's energy; "
            "{'less' if ideal.E_drawn.a < ideal.E_drawn.b else 'more'}; eps "
            "{join(' / ', [number(e, 2) for e in ideal.eps])}; "
            "{join(', ', [f'{law}: {len(law)}' for law in laws])}; {len(laws)} laws; "
            "{number(min(ideal.E_drawn), 1)} to {number(max(ideal.E_drawn), 1)} J")
    assert fill(text, NAMES) == ("a draws 12 % of b's energy; less; eps 0.88 / 0; "
                                 "x: 1, y: 1; 2 laws; 0.5 to 4 J")


def test_a_placeholder_closes_at_the_brace_that_ends_its_expression() -> None:
    """A `}` inside an f-string or a string of the expression does not close it."""
    text = "<{f'{1}' + '}'}> and <{2}>"
    assert placeholders(text) == [(1, 14), (22, 24)]
    assert fill(text, NAMES) == "<1}> and <2>"


@pytest.mark.parametrize(("expression", "says"), [
    ("ideal.to_csv('x.csv')", "only these functions are called"),        # a method call
    ("[number(1) for number in [ideal.to_csv]]", "only these functions"),  # a shadowed one
    ("ideal.__class__", "no name starting with _"),
    ("__import__('os')", "__import__(...): only these functions are called: abs, all,"),
    ("open('x.csv', 'w')", "open(...): only these functions are called"),
    ("ideal.E_drawn.a + other", "unknown name 'other'"),
    ("(lambda: 1)()", "Lambda is not part of the language"),
    ("2 ** 10", "Pow is not part of the language"),
    ("{'a': 1}", "Dict is not part of the language"),
    ("f'{ideal.E_drawn.a:.3f}'", "no conversion or format spec"),
    ("number(**{'value': 1})", "Dict is not part of the language"),
    ("number(**ideal)", "** is not part of the language"),
    ("sorted(ideal.eps, key=ideal.to_csv)", "unexpected keyword argument 'key'"),
    ("ideal.to_csv", "gives a function"),
    ("[law async for law in laws]", "async is not part of the language"),
    ("b'x'", "the constant b'x' is not part of the language"),
    ("ideal.E_drawn.c", "AttributeError"),
    ("number(", "not an expression"),
])
def test_the_language_refuses_what_it_does_not_allow(expression: str, says: str,
                                                     tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Each refusal says why, names the expression, and nothing was written."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(TemplateError) as refused:
        evaluate(expression, NAMES)
    assert says in str(refused.value)
    assert str(refused.value).startswith("{" + expression[:10])
    assert not list(tmp_path.iterdir())


def test_a_placeholder_gives_text_or_an_integer() -> None:
    """A float says how many digits it shows through number(...): refused as it is, in the
    text and inside an f-string."""
    for text in ("{ideal.E_drawn.a}", "{f'{ideal.E_drawn.a} J'}"):
        with pytest.raises(TemplateError, match="not text: format it with number"):
            fill(text, NAMES)
    assert fill("{number(ideal.E_drawn.a)} J", NAMES) == "0.500 J"


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / f"{name}.toml"
    path.write_text(text)
    return path


def test_a_findings_file_evaluates_only_the_values_its_text_reads(tmp_path: Path) -> None:
    """A value that fails stops only the texts that read it, with one line naming the file,
    the value and its expression; values read values defined before them."""
    path = write(tmp_path, "task", """
findings = '''
a: {number(ratio, 3)}

{table(['v', 'E'], [[v, number(e, 2)] for v, e in items(ideal.E_drawn)])}
'''
headline = "{number(broken)}"
[values]
share = "ideal.E_drawn.a / ideal.E_drawn.b"
ratio = "1 / share"
broken = "ideal.E_drawn.nope"
scale = 2.5
""")
    findings = read(path, ("findings", "headline"))
    assert findings.lines("findings", NAMES) == [
        "a: 8.00", "", "| v | E |", "| --- | --- |", "| a | 0.50 |", "| b | 4.0 |", ""]
    with pytest.raises(UserError) as failed:
        findings.lines("headline", NAMES)
    message = str(failed.value)
    assert message.startswith(f"{path}: value broken: {{ideal.E_drawn.nope}}: AttributeError")
    assert "\n" not in message
    assert findings.values["scale"] == 2.5 and findings.lines("readme", NAMES) == []


def test_a_placeholder_that_fails_is_named_with_its_file_and_text(tmp_path: Path) -> None:
    path = write(tmp_path, "task", "findings = 'Drawn: {number(ideal.E_drawn.c)} J.'\n")
    with pytest.raises(UserError, match=r"task.toml: findings: \{number\(ideal.E_drawn.c\)\}: "
                                        "AttributeError"):
        read(path, ("findings",)).lines("findings", NAMES)


@pytest.mark.parametrize("name", ["number", "ideal"])
def test_a_value_may_not_hide_a_function_or_table_of_the_page(tmp_path: Path,
                                                              name: str) -> None:
    path = write(tmp_path, "task", f"findings = 'x'\n[values]\n{name} = \"1\"\n")
    with pytest.raises(UserError, match=f"task.toml: value {name}: the name is the page's"):
        read(path, ("findings",)).lines("findings", NAMES)


@pytest.mark.parametrize(("text", "says"), [
    ("finding = 'x'\n", "unknown key 'finding' (known: order, values, findings)"),
    ("order = 'first'\n", "order = 'first' is not a number"),
    ("values = 3\n", "values is not a table"),
    ("[values]\n_scale = '1'\n", "value '_scale': a name is letters"),
    ("findings = 3\n", "findings is not text"),
])
def test_a_malformed_findings_file_is_refused_in_one_line(tmp_path: Path, text: str,
                                                          says: str) -> None:
    with pytest.raises(UserError, match="task.toml: " + says.replace("(", r"\(").replace(
            ")", r"\)")):
        read(write(tmp_path, "task", text), ("findings",))


def test_findings_files_order_their_subjects(tmp_path: Path) -> None:
    """By `order`, then by name; those without a file or an order after; the section's own
    file is no subject."""
    write(tmp_path, "late", "order = 2\n")
    write(tmp_path, "early", "order = 1.5\n")
    write(tmp_path, "unordered", "findings = 'x'\n")
    write(tmp_path, "_section", "lead = 'x'\n")
    folder = Folder(tmp_path, ("findings",))
    assert folder.in_order(["zeta", "unordered", "late", "early", "alpha"]) == [
        "early", "late", "alpha", "unordered", "zeta"]
    assert [f.path.stem for f in folder.files()] == ["early", "late", "unordered"]


def test_every_shipped_findings_file_describes_a_shipped_scenario_or_sweep() -> None:
    """A renamed scenario or sweep leaves no findings file behind (it would be silently
    left out of the pages)."""
    assert {f.path.stem for f in SCENARIO_FINDINGS.files()} == set(scenarios.available())
    assert {f.path.stem for f in SWEEP_FINDINGS.files()} == {
        p.stem for p in SWEEP_DIR.glob("*.toml")}
