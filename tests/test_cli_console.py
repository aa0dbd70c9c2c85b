"""What the command line prints around the library: its warnings as one plain line each."""

import warnings

import pytest

import jaxheli.cli.identify
from jaxheli.cli import main


def _warns_twice(args):
    """A command whose library call warns the same message from two places, as a skipped frequency fit does."""
    warnings.warn("frequency fit skipped, IWO's best polished alone: no pair\nhas 5 bins", UserWarning)
    warnings.warn("frequency fit skipped, IWO's best polished alone: no pair\nhas 5 bins", UserWarning)
    return 0


@pytest.mark.filterwarnings("default")
def test_a_library_warning_is_one_plain_line_once(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(jaxheli.cli.identify, "_cmd_synth", _warns_twice)
    shown = warnings.showwarning
    assert main(["synth", "--out", str(tmp_path / "f.csv")]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["jaxheli synth: warning: frequency fit skipped, IWO's best polished alone: no pair has 5 bins"]
    assert warnings.showwarning is shown
