"""The command line: `--help` imports no command (its time is `make bench`'s cli_help), every
option says what it does and its default, none is hidden, `cosim --help` names the scenarios,
variants and engines, and a command's mistakes are reported with that command's usage."""

from __future__ import annotations

import argparse
import subprocess
import sys

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


def options(name: str, visible: bool = True) -> list[argparse.Action]:
    """The options of command `name` (its module imported): the visible ones, or all."""
    commands = argparse.ArgumentParser().add_subparsers()
    sub = cli.add_command(commands, name, load=True)
    return [a for a in sub._actions if (a.help != argparse.SUPPRESS or not visible)
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


@pytest.mark.parametrize("name", cli.COMMANDS)
def test_no_option_is_hidden(name):
    """Every option a command takes is in its help: no hidden alias."""
    def strings(actions: list[argparse.Action]) -> list[str]:
        return [s for action in actions for s in action.option_strings]
    assert strings(options(name, visible=False)) == strings(options(name))


def test_cosim_help_names_the_scenarios_variants_engines_and_choices(capsys):
    from harness import scenarios
    from harness.engines import ENGINES
    with pytest.raises(SystemExit):
        cli.main(["cosim", "--help"])
    text = capsys.readouterr().out
    for name in scenarios.available():
        assert f"  {name}" in text
        assert ", ".join(scenarios.load(name).variants) in text
    for engine in ENGINES:
        assert f"  {engine}: " in text
    assert "{all,ideal,realistic}" in text and "{osp,ssp}" in text


@pytest.mark.parametrize("argv", [["cosim", "--scenaro", "x"], ["cosim", "--engine", "fmu"],
                                  ["sweep", "a.toml", "--bogus"]])
def test_a_commands_mistake_shows_that_commands_usage(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        cli.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: python -m harness {argv[0]} ")
    assert err.strip().splitlines()[-1].startswith(f"python -m harness {argv[0]}: error: ")
