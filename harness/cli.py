"""Command line: `python -m harness <command>`.

Each command lives in its own module, which defines add_arguments(parser) and
run(args) -> exit code; COMMANDS names those modules with the command's one-line help.
Only the module of the command being run is imported, so `python -m harness --help` does
not pay for numpy, pandas, FMPy and Dask.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

from harness import interrupts
from harness.errors import UserError

NAME_MAX = 255  # bytes in a file or folder name on Linux, macOS and Windows file systems


class Command(NamedTuple):
    module: str
    help: str
    example: str  # one command line, shown in the command's help


COMMANDS = {
    "build-fmus": Command("harness.fmu.build",
                          "build the FMUs of fmu_src whose inputs changed into build/fmus",
                          "python -m harness build-fmus --force"),
    "cosim": Command("harness.run.cosim",
                     "run scenario variants in an engine (FMPy master, monolithic reference, "
                     "FMI Model Exchange, libcosim at a fixed step or under ECCO, FMPy's SSP "
                     "runner) and write CSV series, summary and plots",
                     "python -m harness cosim --scenario franchetti2021 --variants "
                     "self_regulating --losses ideal"),
    "compare": Command("harness.run.compare",
                       "compare two result CSV files signal by signal within tolerances",
                       "python -m harness compare results/franchetti2021/unbalanced.csv "
                       "build/results/reference/franchetti2021/unbalanced.csv"),
    "ciupitu-example": Command("harness.design.ciupitu_example",
                               "Ciupitu 2018 Section 4 example: eps and max |M_u| for "
                               "parabolic and linear payloads",
                               "python -m harness ciupitu-example --json"),
    "ciupitu-design": Command("harness.design.ciupitu",
                              "choose the Ciupitu counterweight (m2, OA, AB) of franchetti2021 "
                              "by minimising E_drawn",
                              "python -m harness ciupitu-design"),
    "active-design": Command("harness.design.active_spring",
                             "Ciupitu 2018 Fig. 8: the frame joint ordinate Y_B that balances "
                             "a payload change (eq. 27, solved numerically)",
                             "python -m harness active-design --json --mp 1.0"),
    "rocking-design": Command("harness.design.rocking_counterweight",
                              "design Ciupitu's rocking counterweight (Figure 4b) for the "
                              "Section 4 example by least squares on M_u",
                              "python -m harness rocking-design"),
    "sweep": Command("harness.sweeps", "run a parameter sweep file on Dask and write "
                     "results/sweeps/<name>.parquet/.csv/plots",
                     "python -m harness sweep harness/sweeps/table1.toml --out build/sweeps"),
    "study": Command("harness.study",
                     "every variant over random tasks with confidence intervals, on Dask "
                     "(results/study/<scenario>/)",
                     "python -m harness study --scenario franchetti2021 --tasks 3 --out "
                     "build/study"),
    "bench": Command("harness.bench",
                     "benchmarks: FMU step cost against a trivial FMU and in a C host, "
                     "co-simulation real-time factor, step convergence, sweep scaling "
                     "(results/bench)",
                     "python -m harness bench --only fmu_step,cli_help --out build/bench"),
    "docs": Command("harness.report.docs",
                    "write the generated pages: the FMUs' variable tables and list from the "
                    "built FMUs, docs/findings.md and the README's and docs/performance.md's "
                    "figures from the committed results",
                    "python -m harness docs"),
    "cross-check": Command("harness.fmu.cross_check",
                           "write every FMU with its reference result in the FMI cross-check "
                           "layout (build/cross-check) and validate it",
                           "python -m harness cross-check --out build/cross-check"),
}


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Appends '(default: ...)' to an option's help unless the help already states its
    default or the option has none (a flag, or None: the help says what happens then);
    a default path is shown relative to the working directory when inside it. A command's
    epilog (its list of choices) keeps its lines."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("default" in text or not action.option_strings
                or action.default in (None, False, argparse.SUPPRESS)):
            return text
        default = action.default
        if isinstance(default, Path) and default.is_relative_to(Path.cwd()):
            default = default.relative_to(Path.cwd())
        return f"{text} (default: {str(default).replace('%', '%%')})"


def add_command(commands: argparse._SubParsersAction, name: str,
                load: bool) -> argparse.ArgumentParser:
    """The sub-parser of command `name`; with load, its module is imported and its options
    and run function added."""
    command = COMMANDS[name]
    sub = commands.add_parser(name, help=command.help, description=command.help,
                              epilog=f"example:\n  {command.example}",
                              formatter_class=HelpFormatter)
    if load:
        module = importlib.import_module(command.module)
        module.add_arguments(sub)
        if sub.epilog != f"example:\n  {command.example}":  # the module's own epilog after it
            sub.epilog = f"example:\n  {command.example}\n\n{sub.epilog}"
        sub.set_defaults(run=module.run)
    return sub


def parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line, with the options of `command` only (None: the command list)."""
    top = argparse.ArgumentParser(prog="python -m harness", description=__doc__.splitlines()[0])
    commands = top.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        sub = add_command(commands, name, load=name == command)
        if name == command:
            top.set_defaults(subparser=sub)
    return top


def parse(argv: list[str]) -> argparse.Namespace:
    """The parsed command line; a word the command does not know is that command's error,
    reported with its usage (argparse's top level would show its own)."""
    # the top level has no options that take a value: the first other word is the command
    command = next((word for word in argv if not word.startswith("-")), None)
    top = parser(command)
    args, unknown = top.parse_known_args(argv)
    if unknown:
        getattr(args, "subparser", top).error(f"unrecognized arguments: {' '.join(unknown)}")
    return args


def check_out_folder(args: argparse.Namespace) -> None:
    """UserError if --out (every command's folder for its files) has a name longer than a
    file system allows, or names something that exists and is not a folder: found before the
    command does any work."""
    folder = getattr(args, "out", None)
    if not isinstance(folder, Path):
        return
    longest = max((len(os.fsencode(part)) for part in folder.parts), default=0)
    if longest > NAME_MAX:
        raise UserError(f"output folder --out has a name of {longest} bytes, more than the "
                        f"{NAME_MAX} a file system allows")
    if folder.exists() and not folder.is_dir():
        raise UserError(f"output folder --out = {folder} is not writable (it is a file, "
                        "not a folder)")


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:  # a Ctrl-C while the command's module is imported is an interrupt too
        args = parse(argv)
        check_out_folder(args)
        return args.run(args)
    except UserError as error:  # bad input: one clear line, non-zero exit; else a traceback
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if interrupts.received == signal.SIGTERM:
            print("terminated", file=sys.stderr)
            return 143
        print("interrupted", file=sys.stderr)
        return 130
