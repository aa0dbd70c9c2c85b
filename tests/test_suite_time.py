"""``benchmarks/suite_time.py`` reads pytest's closing line and refuses output without one."""

import importlib.util
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "suite_time.py"
_spec = importlib.util.spec_from_file_location("benchmarks_suite_time", _PATH)
suite_time = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(suite_time)


def test_counts_come_from_the_closing_line_not_the_durations():
    out = ("....\n282.12s setup    tests/test_notebook.py::test_runs\n"
           "=========== 1127 passed, 2 failed, 3 skipped in 1472.56s (0:24:32) ===========\n")
    assert suite_time._summary(out) == ({"passed": 1127, "failed": 2, "skipped": 3}, 1472.56)


def test_output_without_a_summary_is_an_error_naming_it():
    with pytest.raises(RuntimeError, match="no pytest summary line"):
        suite_time._summary("ERROR: could not import conftest\n")


def test_the_timed_command_is_readmes():
    readme = (_PATH.parents[1] / "README.md").read_text()
    command = f"{suite_time.INSTALL} && {suite_time.TESTS.removeprefix('. .venv/bin/activate && ')}"
    assert command in readme
