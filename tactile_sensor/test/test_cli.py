"""The ``tactile-sensor`` command itself: its usage, and a command it does not know."""

from __future__ import annotations

import pytest

from tactile_sensor import cli


@pytest.mark.parametrize(("argv", "code"), [(["--help"], 0), (["-h"], 0), ([], 2)])
def test_help_lists_every_command_and_no_command_is_an_error(argv, code, capsys):
    assert cli.main(argv) == code
    out = capsys.readouterr().out
    assert out.startswith("usage: tactile-sensor <command> [options]")
    assert all(f"  {name} " in out for name in cli.SUBCOMMANDS)


def test_an_unknown_command_is_named_in_one_sentence_with_the_choices(capsys):
    assert cli.main(["explode"]) == 2
    err = capsys.readouterr().err
    assert err == ("tactile-sensor: unknown command 'explode'; choose one of "
                   "mock, model, analyze, bringup, bag, grasp, release, tare, self-check.\n")
