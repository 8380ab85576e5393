"""`python -m harness docs` (`make docs`): every generated page. From the built FMUs and the
registrations (`harness.fmu.variable_pages`): docs/fmus.md, docs/variables/<Model>.md and the
section on the reference run and energy ledger in each mechanism's README.md. From the
committed results: docs/findings.md whole (`harness.report.findings`), the README's headline
section (`harness.report.headline`) and docs/performance.md's current figures
(`harness.report.performance`), the last two between markers in hand-written pages.
tests/test_docs.py fails when a page no longer matches what it is made from."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from harness.fmu import build as fmu_build
from harness.io import write_atomic

if TYPE_CHECKING:  # the command's help reads no results
    from harness.report.committed import Results

ROOT = Path(__file__).resolve().parents[2]
FINDINGS = ROOT / "docs" / "findings.md"
README = ROOT / "README.md"
PERFORMANCE = ROOT / "docs" / "performance.md"


def pages(results: Results) -> dict[Path, str]:
    """Every page made from the results, with its text: docs/findings.md whole, the README
    and docs/performance.md with their generated sections replaced."""
    from harness.fmu import variable_pages
    from harness.report.findings import findings_markdown
    from harness.report.headline import headline_section
    from harness.report.performance import performance_section
    from harness.report.text import GENERATED_START

    return {
        FINDINGS: findings_markdown(results),
        README: variable_pages.with_generated_section(
            README.read_text(), headline_section(results), GENERATED_START),
        PERFORMANCE: variable_pages.with_generated_section(
            PERFORMANCE.read_text(), performance_section(results), GENERATED_START),
    }


def write_pages(results: Results | None = None) -> list[Path]:
    """Write the pages whose text changed; the paths written."""
    from harness.report.committed import Results

    written = []
    for path, text in pages(results or Results()).items():
        if not path.is_file() or path.read_text() != text:
            written.append(write_atomic(path, lambda tmp, text=text: tmp.write_text(text)))
    return written


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fmus", type=Path, default=fmu_build.DEFAULT_DEST, metavar="DIR",
                        help="folder of the built FMUs (default build/fmus, `make fmu`)")


def run(args: argparse.Namespace) -> int:
    from harness.fmu import variable_pages

    fmus = [fmu_build.locate(m, args.fmus) for m in fmu_build.MODELS]
    for written in [*variable_pages.write_pages(fmus), *write_pages()]:
        print(written)
    return 0
