"""What the command line prints around the library: its warnings as one plain line each, the polish against its
own objective, and a bad argument as one line without the usage."""

import warnings

import pytest

import jaxheli.cli.identify
from jaxheli.cli import main
from jaxheli.cli.identify import _fit_step_text, _polish_line


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


def test_the_fit_line_says_the_step_and_the_hold():
    assert _fit_step_text({"fit_dt": [0.039783], "hold": "foh"}) == (
        "at 0.03978 s; sticks held first-order; scored at the record's own step")
    assert _fit_step_text({"fit_dt": None, "hold": "zoh"}) == "at each record's own step; sticks held zero-order"


@pytest.mark.parametrize("argv, message", [
    (["identify", "--hold", "xyz"], "jaxheli identify: error: argument --hold: invalid choice: 'xyz' (choose from "
                                    "'auto', 'zoh', 'foh')"),
    (["identify", "--trials", "many"], "jaxheli identify: error: argument --trials: invalid int value: 'many'"),
    (["identfy"], "jaxheli: error: argument COMMAND: invalid choice: 'identfy'"),
])
def test_a_bad_argument_is_one_line_without_the_usage(argv, message, capsys):
    with pytest.raises(SystemExit) as done:
        main(argv)
    lines = capsys.readouterr().err.splitlines()
    assert done.value.code == 2 and len(lines) == 2
    assert lines[0].startswith(message) and lines[1] == f"see {message.split(':')[0]} --help"
