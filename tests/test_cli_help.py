"""Every command's ``--help``: it prints, exits 0, and shows no argparse escapes (``%%``) or stale wording."""

import argparse

import pytest

from jaxheli.cli import build_parser, main


def _commands() -> list[str]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(sub.choices)


def test_every_command_is_listed():
    assert {"identify", "verify", "check", "diagnose", "blind", "report"} <= set(_commands())


@pytest.mark.parametrize("command", _commands())
def test_help_prints_plain_text(command, capsys):
    with pytest.raises(SystemExit) as done:
        main([command, "--help"])
    text = capsys.readouterr().out
    assert done.value.code == 0 and f"jaxheli {command}" in text
    assert "%%" not in text and "Done-when" not in text


def test_check_names_every_log_kind_it_reads(capsys):
    with pytest.raises(SystemExit):
        main(["check", "--help"])
    text = capsys.readouterr().out
    assert all(kind in text for kind in (".mat", ".csv", ".npz", ".px4log", ".bin", ".ulg"))
