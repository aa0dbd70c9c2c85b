"""One command-line grammar (issue 34 item 4): every command that reads flights takes them as ``--data
FILE[:t0-t1]`` (``--validate FILE[:t0-t1]`` for a held-out flight), its ``--help`` says so, the window parses the same
everywhere, and the old forms still parse to the same arguments, each with one deprecation line. Parsing only: no
command runs."""

import argparse
from types import SimpleNamespace

import pytest

import jaxheli.cli._options as options
import jaxheli.cli.prepare
from jaxheli.cli import build_parser
from jaxheli.cli._options import FLIGHT
from jaxheli.flights import parse_spec

READERS = {"check", "prepare", "localise", "evaluate", "identify", "verify", "diagnose", "report", "bench"}
"""Commands that read flights."""
WRITERS = {"synth", "blind", "trials-scaling"}
"""Commands that make their own flights."""


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _parse(argv: list[str]) -> dict:
    """The arguments of ``jaxheli ARGV`` as a dict, without the handler."""
    return {k: v for k, v in vars(build_parser().parse_args(argv)).items() if k != "func"}


def test_every_command_is_a_reader_or_a_writer():
    assert set(_subparsers()) == READERS | WRITERS


@pytest.mark.parametrize("command", sorted(READERS))
def test_help_shows_the_flight_option(command):
    text = " ".join(_subparsers()[command].format_help().split())
    assert f"--data {FLIGHT}" in text and "t0 <= t <= t1" in text
    assert "--window T0:T1" not in text and "--experiment-data" not in text


@pytest.mark.parametrize("command", sorted(READERS | WRITERS))
def test_every_flight_is_an_option_shown_the_same_way(command):
    """No positional flight and no flight option with a metavar of its own: every option that names a flight is
    ``--data`` or ``--validate`` and shows ``FILE[:t0-t1]``."""
    shown = [a for a in _subparsers()[command]._actions if a.help != argparse.SUPPRESS]
    assert "FILE" not in {a.metavar for a in shown if not a.option_strings}
    flights = {a.dest for a in shown if a.metavar == FLIGHT}
    assert flights == ({"data", "validate"} & {a.dest for a in shown} if command in READERS else set())


@pytest.mark.parametrize(("old", "new"), [
    (["check", "f.mat", "--out", "o"], ["check", "--data", "f.mat", "--out", "o"]),
    (["check", "--out", "o", "f.mat"], ["check", "--out", "o", "--data", "f.mat"]),
    (["prepare", "f.mat", "--out", "o.npz"], ["prepare", "--data", "f.mat", "--out", "o.npz"]),
    (["prepare", "f.mat", "--window", "10:70", "--out", "o.npz"],
     ["prepare", "--data", "f.mat:10-70", "--out", "o.npz"]),
    (["prepare", "--window", "10.5:70", "f.mat", "--out", "o.npz"],
     ["prepare", "--data", "f.mat:10.5-70", "--out", "o.npz"]),
    (["diagnose", "--model", "table2", "--train", "a.npz", "--validate", "b.mat:5-"],
     ["diagnose", "--model", "table2", "--data", "a.npz", "--validate", "b.mat:5-"]),
    (["identify", "--train", "a.mat:0-4", "b.mat", "--validate", "c.mat"],
     ["identify", "--data", "a.mat:0-4", "--data", "b.mat", "--validate", "c.mat"]),
    (["identify", "--train", "a.mat", "--train", "b.mat"], ["identify", "--data", "a.mat", "b.mat"]),
    (["verify", "--model", "m", "--data", "a.mat", "b.mat:1-9", "--out", "o"],
     ["verify", "--model", "m", "--data", "a.mat", "--data", "b.mat:1-9", "--out", "o"]),
    (["bench", "--experiment-data", "a.mat"], ["bench", "--data", "a.mat"]),
    (["report", "r", "--data", "a.mat", "--data", "b.mat"], ["report", "--data", "a.mat", "--data", "b.mat", "r"]),
])
def test_old_and_new_forms_parse_the_same(old, new):
    assert _parse(old) == _parse(new)


@pytest.mark.parametrize(("argv", "notes"), [
    (["check", "f.mat", "--out", "o"], ["jaxheli check: note: 'jaxheli check FILE' is deprecated; use --data FILE"]),
    (["prepare", "f.mat", "--window", "1:2", "--out", "o.npz"],
     ["jaxheli prepare: note: 'jaxheli prepare FILE' is deprecated; use --data FILE",
      "jaxheli prepare: note: '--window T0:T1' is deprecated; use --data FILE:T0-T1"]),
    (["bench", "--experiment-data", "a.mat"],
     ["jaxheli bench: note: '--experiment-data FILE' is deprecated; use --data FILE"]),
    (["check", "--data", "f.mat"], []),
    (["diagnose", "--model", "m", "--train", "a.mat", "--validate", "b.mat"], []),  # role names, not deprecated
    (["identify", "--train", "a.mat"], []),
])
def test_an_old_form_prints_one_note_a_new_one_none(argv, notes, capsys):
    _parse(argv)
    assert capsys.readouterr().err.splitlines() == notes


@pytest.mark.parametrize(("argv", "message"), [
    (["check", "f.mat", "--data", "g.mat"], "argument --data: not allowed with argument FILE"),
    (["check", "--out", "o"], "one of the arguments --data is required"),
    (["evaluate", "--model", "m", "--data", "a.mat", "--data", "b.mat"], "argument --data: names one flight"),
    (["diagnose", "--model", "m", "--data", "a.mat", "--train", "b.mat", "--validate", "c.mat"],
     "argument --data/--train: names one flight"),
    (["prepare", "f.mat", "--window", "9:1", "--out", "o.npz"], "the window's end 1.0 s must come after its start"),
    (["prepare", "f.mat", "--window", "abc", "--out", "o.npz"], "expected T0:T1 in seconds"),
    (["prepare", "--data", "f.mat:1-5", "--window", "1:2", "--out", "o.npz"], "f.mat:1-5 already has a window"),
    (["bench", "--data", "a.mat", "--experiment-data", "b.mat"], "give the flight once, as --data"),
])
def test_a_flight_given_twice_or_not_at_all_is_one_error_line(argv, message, capsys):
    with pytest.raises(SystemExit) as done:
        _parse(argv)
    error = [line for line in capsys.readouterr().err.splitlines() if ": error: " in line]
    assert done.value.code == 2 and len(error) == 1 and message in error[0]


class _Read(Exception):
    """The flight a command asked for: ``(name, t0, t1)``."""


SPEC = r"C:\flights\a b.mat:1.5-20"
"""A window on a Windows path (the drive's colon is not the window's)."""


@pytest.mark.parametrize(("argv", "nth"), [
    (["check", "--data", SPEC], 1),
    (["localise", "--model", "table2", "--data", SPEC], 1),
    (["evaluate", "--model", "table2", "--data", SPEC], 1),
    (["identify", "--data", "a.mat", SPEC], 2),
    (["identify", "--data", "a.mat", "--validate", SPEC], 2),
    (["verify", "--model", "table2", "--data", SPEC, "--out", "o"], 1),
    (["diagnose", "--model", "table2", "--data", SPEC, "--validate", "b.mat"], 1),
    (["diagnose", "--model", "table2", "--data", "a.mat", "--validate", SPEC], 2),
    (["prepare", "--data", SPEC, "--out", "o.npz"], 1),
    (["prepare", r"C:\flights\a b.mat", "--window", "1.5:20", "--out", "o.npz"], 1),
])
def test_every_command_reads_the_window_the_same_way(argv, nth, monkeypatch):
    """Each command hands its flights to the one window parser (:func:`jaxheli.flights.parse_spec`), through
    :func:`jaxheli.cli._options.read_flight`: a stand-in for the loader stops the command at its ``nth`` flight,
    which must be ``SPEC``'s (the flights before it: stand-ins without data, left unprepared)."""
    read = []

    def load(spec, **options):
        read.append(parse_spec(spec))
        if len(read) == nth:
            raise _Read(read[-1])
        return SimpleNamespace(metadata={}, source=spec)

    def prepare(name, *, window, **steps):  # prepare cuts the window in its own chain, its first step
        raise _Read((name, *window))

    monkeypatch.setattr(options, "load_flight", load)
    monkeypatch.setattr(jaxheli.cli.prepare, "read_flight", lambda spec, args: spec)
    monkeypatch.setattr(jaxheli.cli.prepare, "prepare", prepare)
    args = build_parser().parse_args(argv)
    with pytest.raises(_Read) as stopped:
        args.func(args)
    assert stopped.value.args[0] == (r"C:\flights\a b.mat", 1.5, 20.0)


def test_a_windows_path_without_a_window_is_taken_whole():
    assert parse_spec(r"C:\flights\a.mat") == (r"C:\flights\a.mat", None, None)
    assert _parse(["evaluate", "--model", "m", "--data", r"C:\flights\a.mat"])["data"] == r"C:\flights\a.mat"
