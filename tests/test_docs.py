"""The documentation in docs/ stays true to the code and the committed results, and the
repository stands on its own."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pandas as pd
import pytest
from fmpy import read_model_description

from harness import registry
from harness.drive.metrics import METRICS
from harness.fmu import build as fmu_build
from harness.fmu import variable_pages
from harness.report import docs, text
from harness.report.committed import Results
from harness.run.results import RESULTS_DIR, SUMMARY_COLUMNS

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
# references to documents that are not in the repository (written so that this file does
# not match them itself)
OUTSIDE = re.compile(r"\bSPEC\b|(?i:PITFALL[S]|\.\./shar[e]d|/work/shar[e]d|\bthe\s+issue\b)")
SKIP_DIRS = {".git", ".venv", "build", "results", "__pycache__", ".pytest_cache",
             ".ruff_cache"}
TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".c", ".h", ".cfg", ".ini", ".yml", ".yaml",
                 ".xml", ".json", ".ssd", ""}


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_variable_pages_match_the_built_fmus(model):
    """docs/variables/<Model>.md is what `make docs` writes for the FMU as built now."""
    md = read_model_description(str(fmu_build.fmu_path(model)))
    page = variable_pages.DOCS_VARIABLES / f"{model}.md"
    assert page.is_file(), f"{page} is missing: run `make docs`"
    assert page.read_text() == variable_pages.variables_markdown(md), (
        f"{page.relative_to(ROOT)} is out of date: run `make docs`")


def test_every_metric_and_summary_column_is_documented():
    text = (DOCS / "results.md").read_text()
    missing = [name for name in (*METRICS, *SUMMARY_COLUMNS) if f"`{name}`" not in text]
    assert not missing, f"docs/results.md does not explain {missing}"


def repository_files() -> list[Path]:
    """The repository's text files (not its venv, build output or generated results)."""
    files = []
    for path in ROOT.rglob("*"):
        parts = set(path.relative_to(ROOT).parts)
        if (path.is_file() and not parts & SKIP_DIRS
                and not any(p.endswith(".egg-info") for p in parts)
                and path.suffix in TEXT_SUFFIXES):
            files.append(path)
    return files


def test_nothing_refers_to_documents_outside_the_repository():
    hits = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
            for path in repository_files()
            for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1)
            if OUTSIDE.search(line)]
    assert not hits, "point these to docs/ instead:\n" + "\n".join(hits)


LINK = re.compile(r"\]\(([^)#\s]+)(#[^)\s]*)?\)")


def test_relative_links_resolve():
    """In every Markdown page of the repository (the mechanisms' READMEs included)."""
    tracked = subprocess.run(["git", "ls-files", "*.md"], cwd=ROOT, capture_output=True,
                             text=True, check=True).stdout.split()
    pages = [ROOT / name for name in tracked]
    assert ROOT / "fmu_src/mechanisms/ciupitu/README.md" in pages
    broken = [f"{page.relative_to(ROOT)}: {target}" for page in pages
              for target, _ in LINK.findall(page.read_text())
              if "://" not in target and not (page.parent / target).exists()]
    assert not broken, f"broken links: {broken}"


def test_the_fmu_index_lists_every_fmu_by_its_slave_script() -> None:
    """docs/fmus.md is what `make docs` writes for the FMUs as built now: the slave script
    of every registered FMU, and no other, each with its variable page; the README points
    to it."""
    descriptions = [read_model_description(str(fmu_build.fmu_path(m))) for m in fmu_build.MODELS]
    index = variable_pages.FMU_INDEX
    assert index.is_file(), f"{index} is missing: run `make docs`"
    assert index.read_text() == variable_pages.fmu_index_markdown(descriptions), (
        f"{index.relative_to(ROOT)} is out of date: run `make docs`")
    listed = re.findall(r"\[`(fmu_src/[\w/]+/([A-Z]\w+)\.py)`\]", index.read_text())
    assert [model for _, model in listed] == list(fmu_build.MODELS)
    for model, script in registry.scripts().items():
        assert (script.relative_to(ROOT).as_posix(), model) in listed, model
    assert "(docs/fmus.md)" in (ROOT / "README.md").read_text()


@pytest.mark.parametrize("model", sorted(registry.mechanisms()))
def test_each_mechanism_readme_states_its_reference_run_and_ledger(model: str) -> None:
    """The README beside the slave script holds the section `make docs` writes from the
    registration (reference run, ledger identity), once and up to date."""
    script, found = registry.scripts()[model], registry.mechanisms()[model]
    readme = (script.parent / "README.md").read_text()
    section = variable_pages.reference_and_ledger_markdown(script, found)
    assert readme.count(variable_pages.GENERATED_START) == 1
    assert variable_pages.with_generated_section(readme, section) == readme, (
        f"{script.parent.relative_to(ROOT)}/README.md is out of date: run `make docs`")
    assert variable_pages.ledger_identity(found.ledger) in readme


def test_the_ledger_page_states_every_mechanism_ledger() -> None:
    """docs/energy_ledger.md's list: one line per mechanism, its registration's identity."""
    page = (DOCS / "energy_ledger.md").read_text()
    lines = {" ".join(line.split()) for line in page.splitlines()}
    for model, found in registry.mechanisms().items():
        assert f"{model}: {variable_pages.ledger_identity(found.ledger)}" in lines, model


def test_the_generated_section_replaces_only_itself() -> None:
    """with_generated_section appends the section once, then replaces it in place, leaving
    the hand-written text before and after it unchanged."""
    section = "## Reference run and energy ledger\n\n" + variable_pages.GENERATED_START + (
        "\n\nA.\n\n" + variable_pages.GENERATED_END + "\n")
    first = variable_pages.with_generated_section("# M\n\nText.\n", section)
    assert first == "# M\n\nText.\n\n" + section
    changed = first.replace("A.", "B.") + "\n## After\n"
    assert variable_pages.with_generated_section(changed, section) == first + "\n## After\n"


def test_the_pages_made_from_the_results_are_fresh() -> None:
    """docs/findings.md, the README's headline section and docs/performance.md's figures are
    what `make docs` writes from the committed CSV files: every table and every number of
    every sentence. The README and performance.md hold their section once."""
    for path, page_text in docs.pages(Results()).items():
        assert path.read_text() == page_text, (
            f"{path.relative_to(ROOT)} is out of date: run `make docs`")
    for page in (docs.README, docs.PERFORMANCE):
        assert page.read_text().count(text.GENERATED_START) == 1, page
    assert "<!--=" not in docs.README.read_text()


def test_the_generated_pages_follow_the_csv_files(tmp_path: Path) -> None:
    """From a copy of the committed CSV files in which franchetti2021's self-regulation draws
    0.0123456 J (0.0234567 J with real parts), the findings' table and one-line answer and the
    README's table print those values and what follows from them, not the committed ones; and
    the table1 sweep's finding its payload_max of 5 kg (the payloads beyond it listed)."""
    copy = tmp_path / "results"
    shutil.copytree(RESULTS_DIR, copy, ignore=shutil.ignore_patterns("*.parquet",
                                                                              "*.png"))
    path = copy / "franchetti2021" / "summary.csv"
    summary = pd.read_csv(path)
    summary.loc[summary.variant == "self_regulating", "E_drawn"] = 0.0123456
    summary.to_csv(path, index=False)
    unregulated = summary.set_index("variant").E_drawn.unregulated
    real_path = copy / "franchetti2021" / "realistic" / "summary.csv"
    real = pd.read_csv(real_path)
    real.loc[real.variant == "self_regulating", "E_drawn"] = 0.0234567
    real.to_csv(real_path, index=False)
    sweep = copy / "sweeps" / "table1.csv"
    pd.read_csv(sweep).assign(payload_max=5.0).to_csv(sweep, index=False)
    pages = docs.pages(Results(copy))
    findings = " ".join(pages[docs.FINDINGS].split())
    assert "for payloads up to payload_max = 5.00 kg, and " in findings
    assert "% at 6 kg" in findings and "% at 6 kg" not in " ".join(
        docs.FINDINGS.read_text().split())
    answer = f"cuts the drive's energy to {text.percent(0.0123456 / unregulated, 2)} % of"
    for page in (docs.FINDINGS, docs.README):
        assert answer in pages[page], page
    realistic = text.number(pd.read_csv(copy / "franchetti2021" / "realistic" / "summary.csv")
                              .set_index("variant").E_drawn.self_regulating, 4)
    assert f"| `self_regulating` | 0.01235 | {realistic} |" in pages[docs.FINDINGS]
    # the README's row: the least E_drawn on the paper's task with real parts
    assert "| `self_regulating`: 0.0235 (" in pages[docs.README]
    committed = docs.pages(Results())
    assert pages[docs.PERFORMANCE] == committed[docs.PERFORMANCE]
    drawn = pd.read_csv(RESULTS_DIR / "franchetti2021" / "summary.csv").set_index(
        "variant").E_drawn.self_regulating
    assert f"| `self_regulating` | {text.number(drawn, 4)} |" in committed[docs.FINDINGS]
    assert "0.01235" not in committed[docs.FINDINGS]


def test_numbers_are_printed_to_their_significant_digits() -> None:
    assert text.number(0.069907, 3) == "0.0699"
    assert text.number(125.92, 5) == "125.92"
    assert text.number(10.0, 4) == "10.00"
    assert text.number(0.00099999, 2) == "0.0010"   # rounded across a decade
    assert text.number(4.2e-4, 2) == "4.2e-4"
    assert text.number(-1.1749, 3) == "-1.17"
    assert text.number(float("nan")) == "-"
    assert text.span([0.9931, 0.9987], 3, 100) == "99.3-99.9"
    assert text.falls_or_rises(0.86, 0.823) == "falls from 0.860 to 0.823"
    assert text.more_or_less(-0.0846, "J") == "0.0846 J less"


def test_generated_prose_is_wrapped_without_starting_a_markdown_block() -> None:
    """Paragraphs wrap to WIDTH; a piece that would open a list, heading or table on a new
    line stays on the line before; tables and headings are kept whole."""
    prose = ("word " * 60).strip()
    assert all(len(line) <= text.WIDTH for line in text.wrapped([prose]))
    assert " ".join(text.wrapped([prose])) == prose
    assert text.wrapped(["w" * 90 + " - b", "| a | b |", "# " + "h " * 60]) == [
        "w" * 90 + " - b", "| a | b |", "# " + "h " * 60]


def test_the_readme_is_a_front_page() -> None:
    """At most 150 lines; how to run a command in the venv; the FMUs' interfaces and the
    hosts they ran in; the terms it uses defined; every page of docs/ in its table."""
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 150
    assert ".venv/bin/python -m harness" in readme and "make cosim" in readme
    for named in ("Model Exchange", "Co-Simulation", "FMPy", "libcosim", "fmusim", "fmuCheck",
                  "PyFMI", "OMSimulator", "**E_drawn**", "**eps**", "ECCO, which"):
        assert named in readme, named
    pages = {p.name for p in (ROOT / "docs").glob("*.md")}
    linked = set(re.findall(r"\(docs/([\w.-]+\.md)", readme))
    assert pages <= linked, sorted(pages - linked)
