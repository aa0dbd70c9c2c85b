"""The convergence plot: the generations of the search and, beside them, the polish's rounds."""

import numpy as np
import pytest

from jaxheli import plots

ROUNDS = [[5.0, 2.0], [2.5, 1.0], [1.0, 0.8]]
"""A polish's objective at the start and end of each of three rounds."""


@pytest.fixture
def drawn(monkeypatch):
    """The figures the plot functions save, in order."""
    figures, save = [], plots._save
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig) or save(fig, path))
    return figures


def test_the_polish_rounds_are_drawn_beside_the_generations(drawn, tmp_path):
    histories = {"trial 0": np.geomspace(9.0, 5.0, 20), "trial 1": np.geomspace(8.0, 6.0, 20)}
    path = plots.plot_convergence(histories, tmp_path / "c.png", "iwo+polish", {"polish (output-error)": ROUNDS})
    assert path.read_bytes()[:4] == b"\x89PNG"
    search, polish = drawn[0].axes
    assert search.get_xlabel() == "generation" and len(search.get_lines()) == 2
    assert polish.get_xlabel() == "polish round" and len(polish.get_lines()) == len(ROUNDS)
    for k, (line, ends) in enumerate(zip(polish.get_lines(), ROUNDS)):
        np.testing.assert_array_equal(line.get_xdata(), [k, k + 1])
        np.testing.assert_array_equal(line.get_ydata(), ends)
    assert [t.get_text() for t in polish.get_legend().get_texts()] == ["polish (output-error)"]


def test_a_polish_without_generations_is_drawn_alone(drawn, tmp_path):
    plots.plot_convergence({}, tmp_path / "c.png", polish={"freq+polish (pearson)": ROUNDS[:1]})
    (polish,) = drawn[0].axes
    assert polish.get_xlabel() == "polish round" and len(polish.get_lines()) == 1


def test_a_polish_that_did_not_move_gets_a_readable_axis(drawn, tmp_path):
    plots.plot_convergence({}, tmp_path / "c.png", polish={"polish": [[0.8137794967375505, 0.8137794967375498]]})
    low, high = drawn[0].axes[0].get_ylim()
    assert low < 0.5 and high > 2.0
