"""The command line: `--help` imports no command (its time is `make bench`'s cli_help) and every
option says what it does and its default."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from harness import cli

HEAVY = ("numpy", "pandas", "fmpy", "matplotlib", "dask", "control")


def test_top_level_help_imports_no_command():
    """`python -m harness --help` lists the commands without importing their modules."""
    probe = ("import sys\nfrom harness import cli\n"
             "try:\n    cli.main(['--help'])\nexcept SystemExit as stop:\n"
             "    assert stop.code == 0\n"
             f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
    for name in cli.COMMANDS:
        assert name in out


def options(name: str) -> list[argparse.Action]:
    """The visible options of command `name` (its module imported)."""
    commands = argparse.ArgumentParser().add_subparsers()
    sub = cli.add_command(commands, name, load=True)
    return [a for a in sub._actions if a.help != argparse.SUPPRESS
            and not isinstance(a, argparse._HelpAction)]


@pytest.mark.parametrize("name", cli.COMMANDS)
def test_command_help(name, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main([name, "--help"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: python -m harness {name}")


@pytest.mark.parametrize("name", cli.COMMANDS)
def test_every_option_has_help_with_its_default(name):
    formatter = cli.HelpFormatter("python -m harness")
    for action in options(name):
        assert action.help, f"{name} {action.dest}: no help text"
        takes_value = action.option_strings and action.nargs != 0
        if takes_value:
            text = formatter._expand_help(action)
            assert "default" in text, f"{name} {action.option_strings[0]}: no default in help"


@pytest.mark.parametrize(("argv", "dest", "value"), [
    (["build-fmus", "--dest", "x"], "dest", Path("x")),
    (["cross-check", "--dest", "x"], "dest", Path("x")),
    (["system", "--variant", "unbalanced"], "variant", "unbalanced"),
    (["bench", "--steps", "7"], "steps", 7),
])
def test_former_option_spellings_still_work(argv, dest, value):
    """Options renamed for consistency keep their former spelling, out of the help."""
    args = cli.parser(argv[0]).parse_args(argv)
    assert getattr(args, dest) == value
    shown = {option for action in options(argv[0]) for option in action.option_strings}
    assert argv[1] not in shown
