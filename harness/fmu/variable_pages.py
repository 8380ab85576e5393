"""`python -m harness docs` (`make docs`): docs/variables/<Model>.md, the variable table of each
built FMU's model description; tests/test_docs.py fails when a page no longer matches."""

from __future__ import annotations

import argparse
from pathlib import Path

from fmpy import read_model_description
from fmpy.model_description import ModelDescription

from harness.fmu import build as fmu_build
from harness.fmu.docs import VARIABLE_COLUMNS, variable_cells

DOCS_VARIABLES = Path(__file__).resolve().parents[2] / "docs" / "variables"


def variables_markdown(md: ModelDescription) -> str:
    """The variable table of a built FMU as a Markdown page (docs/variables/<Model>.md)."""
    def row(cells: tuple[str, ...]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"
    experiment = md.defaultExperiment
    default = ("none" if experiment is None else
               f"start {experiment.startTime} s, stop {experiment.stopTime} s, "
               f"step {experiment.stepSize} s")
    table = [row(VARIABLE_COLUMNS), row(tuple("---" for _ in VARIABLE_COLUMNS))]
    table += [row((f"`{cells[0]}`", *cells[1:])) for cells in variable_cells(md)]
    return "\n".join([
        f"# {md.modelName}: variables", "",
        f"{md.description or ''}", "",
        "Generated from the built FMU's modelDescription.xml by `make docs`; "
        "`tests/test_docs.py` fails when this page no longer matches the FMU. SI units, "
        "angles in radians. The equations are in [../mechanisms.md](../mechanisms.md) and "
        "[../drive_and_controller.md](../drive_and_controller.md).", "",
        f"Default experiment: {default}.", "",
        *table, ""])


def write_variable_pages(fmus: list[Path], folder: Path = DOCS_VARIABLES) -> list[Path]:
    """docs/variables/<Model>.md for each built FMU."""
    folder.mkdir(parents=True, exist_ok=True)
    pages = []
    for fmu in fmus:
        md = read_model_description(str(fmu))
        page = folder / f"{md.modelName}.md"
        page.write_text(variables_markdown(md))
        pages.append(page)
    return pages


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--fmus", type=Path, default=fmu_build.DEFAULT_DEST, metavar="DIR",
                        help="folder of the built FMUs (default build/fmus, `make fmu`)")


def run(args: argparse.Namespace) -> int:
    for written in write_variable_pages([fmu_build.locate(m, args.fmus)
                                         for m in fmu_build.MODELS]):
        print(written)
    return 0
