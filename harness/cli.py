"""Command line: `python -m harness <command>`."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from harness import fmu_build


def _build_fmus(args: argparse.Namespace) -> int:
    for fmu in fmu_build.build_all(args.dest):
        print(fmu)
    return 0


def parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(prog="python -m harness", description=__doc__)
    commands = top.add_subparsers(dest="command", required=True)

    build = commands.add_parser("build-fmus", help="build every FMU into build/fmus")
    build.add_argument("--dest", type=fmu_build.Path, default=fmu_build.DEFAULT_DEST)
    build.set_defaults(run=_build_fmus)
    return top


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    return args.run(args)
