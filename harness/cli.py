"""Command line: `python -m harness <command>`.

Each command lives in its own module, which defines COMMAND (its name), HELP,
add_arguments(parser) and run(args) -> exit code; COMMANDS lists those modules.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from harness.errors import UserError

COMMANDS = ("harness.fmu_build", "harness.cosim", "harness.system", "harness.compare",
            "harness.ciupitu_example", "harness.ciupitu_design", "harness.sweep",
            "harness.bench", "harness.cross_check")


def parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(prog="python -m harness", description=__doc__.splitlines()[0])
    commands = top.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        module = importlib.import_module(name)
        sub = commands.add_parser(module.COMMAND, help=module.HELP, description=module.HELP)
        module.add_arguments(sub)
        sub.set_defaults(run=module.run)
    return top


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.run(args)
    except UserError as error:  # bad input: one clear line, non-zero exit; else a traceback
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
