"""What the command line prints around the library: its warnings as one plain line each."""

import warnings

import pytest

import jaxheli.cli.identify
from jaxheli.cli import main
from jaxheli.cli.identify import _polish_line


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


POLISH = {"objective": "output-error", "objective_before": 12.3, "objective_after": 4.5, "cost_before": 1.598,
          "cost_after": 7.968}


def test_the_polish_reports_its_own_objective_and_the_search_cost_apart():
    assert _polish_line(POLISH, "pearson") == (
        "polish: output error per sample 12.3 -> 4.5 (its objective); search cost (pearson) 1.598 -> 7.968, "
        "not minimised by the polish")
    pure = {**POLISH, "objective": "pearson", "objective_before": 1.598, "objective_after": 0.9}
    assert _polish_line(pure, "pearson") == ("polish: Pearson cost (paper Eq. 7) 1.598 -> 0.9 (its objective, also "
                                             "the search cost)")
