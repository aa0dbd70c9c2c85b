"""Progress lines: a diagnosis at the command line names each stage on stderr, stamped, with no silence of 5 s or
more on the console, and ``--quiet`` leaves only the result."""

import io
import re
import sys
import threading
import time

import pytest

from jaxheli._progress import HEARTBEAT_S, left, note, reporting, stage
from jaxheli.cli import main
from jaxheli.io import save_npz
from test_diagnose import DELAY, _flight

STAMP = re.compile(r"^\[ *\d+\.\d s\] ")
SILENCE_S = 5.0


class _Console(io.StringIO):
    """A console stream that keeps the time of each write, in ``times`` (shared by stdout and stderr)."""

    def __init__(self, times: list[float]):
        super().__init__()
        self.times = times

    def write(self, text: str) -> int:
        if text:
            self.times.append(time.perf_counter())
        return super().write(text)


def _run(argv, monkeypatch):
    """``jaxheli ARGV`` with stdout and stderr captured: ``(stdout, stderr, longest silence in s)``, the silence
    counted from the call to its return between any two writes to either stream."""
    times = [time.perf_counter()]
    out, err = _Console(times), _Console(times)
    with monkeypatch.context() as m:
        m.setattr(sys, "stdout", out)
        m.setattr(sys, "stderr", err)
        assert main(argv) == 0
    times.append(time.perf_counter())
    return out.getvalue(), err.getvalue(), max(b - a for a, b in zip(times, times[1:]))


@pytest.fixture(scope="module")
def flights(tmp_path_factory):
    """The flight pair of tests/test_diagnose.py (80 ms lon input delay) as files."""
    folder = tmp_path_factory.mktemp("progress")
    for name, seed, amplitude in (("train", 3, 0.2), ("validate", 4, 0.25)):
        save_npz(_flight(DELAY, seed, amplitude), folder / f"{name}.npz")
    return folder


STAGES = ("consistency check of both flights ...", "consistency check of both flights: ",
          "predictors of both flights, the restart filter tuned", "restart filter level",
          "ranking 1 candidate effect(s) on the validation flight, the base model frozen",
          "candidate rows and the reference on the frozen base model (15 LM steps, one solve) ...",
          "best so far: input_delay shrinks the held-out gap", "gaps and localisation of the base model on both flights ...",
          "gaps and localisation of the base model on both flights: done", "plots in ")
"""Lines of the stages of a diagnosis on the frozen base (those of a joint one: tests/test_diagnose.py)."""


def test_a_diagnosis_reports_every_stage_and_quiet_only_the_result(flights, tmp_path, monkeypatch):
    argv = ["diagnose", "--model", "table2", "--train", str(flights / "train.npz"), "--validate",
            str(flights / "validate.npz"), "--effects", "input_delay", "--max-steps", "15", "--top", "1",
            "--frozen-base"]
    out, err, silence = _run([*argv, "--out", str(tmp_path / "loud")], monkeypatch)
    lines = err.splitlines()
    assert lines and all(STAMP.match(line) for line in lines), err
    for text in STAGES:
        assert any(text in line for line in lines), (text, err)
    assert silence < SILENCE_S, err
    assert "verdict: input_delay" in out
    quiet_out, quiet_err, _ = _run([*argv, "--out", str(tmp_path / "quiet"), "--quiet"], monkeypatch)
    assert quiet_err == ""
    assert quiet_out == out.replace(str(tmp_path / "loud"), str(tmp_path / "quiet"))  # the same result
    assert not any(t.name == "jaxheli-progress" for t in threading.enumerate())


def test_the_watchdog_names_a_long_stage_and_a_library_caller_sees_nothing(capsys):
    with stage("outside any reporting"):
        note("unseen")
    assert capsys.readouterr().err == ""
    with reporting():
        with stage("a long wait") as now:
            time.sleep(HEARTBEAT_S + 0.5)
            now.outcome = "over"
        with reporting(False):
            note("muted")
    lines = capsys.readouterr().err.splitlines()
    bare = [STAMP.sub("", line) for line in lines]
    assert bare[:2] == ["a long wait ...", f"  ... a long wait ({HEARTBEAT_S:.0f} s)"] and len(bare) == 3
    assert re.fullmatch(r"a long wait: over \(4\.[5-9] s\)", bare[2]), bare
    assert left(3, 10, 90.0) == "3 of 10 done in 90 s, about 210 s left" and left(10, 10, 5.0) == "10 of 10 done in 5 s"
