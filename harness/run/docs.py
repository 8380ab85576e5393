"""`python -m harness docs` (`make docs`): every generated page. From the built FMUs and the
registrations (`harness.fmu.variable_pages`): docs/fmus.md, docs/variables/<Model>.md and the
section on the reference run and energy ledger in each mechanism's README.md. From the
committed results (`harness.run.report`): docs/findings.md, the README's headline table and
docs/performance.md's current figures. tests/test_docs.py fails when a page no longer
matches what it is made from."""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.fmu import build as fmu_build
from harness.fmu import variable_pages
from harness.run import report


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fmus", type=Path, default=fmu_build.DEFAULT_DEST, metavar="DIR",
                        help="folder of the built FMUs (default build/fmus, `make fmu`)")


def run(args: argparse.Namespace) -> int:
    fmus = [fmu_build.locate(m, args.fmus) for m in fmu_build.MODELS]
    for written in [*variable_pages.write_pages(fmus), *report.write_pages()]:
        print(written)
    return 0
