"""Progress lines: the watchdog and the library's silence, and :func:`console_run`, the console capture of the
command-line test (tests/test_diagnose.py: a diagnosis names each stage on stderr, stamped, with no silence of 5 s or
more, and ``--quiet`` leaves only the result)."""

import io
import re
import sys
import time

from jaxheli._progress import HEARTBEAT_S, left, note, reporting, stage
from jaxheli.cli import main

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


def console_run(argv: list[str]) -> tuple[str, str, float]:
    """``jaxheli ARGV`` with stdout and stderr captured: ``(stdout, stderr, longest silence in s)``, the silence
    counted from the call to its return between any two writes to either stream."""
    times = [time.perf_counter()]
    out, err = _Console(times), _Console(times)
    saved = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = out, err
    try:
        assert main(argv) == 0
    finally:
        sys.stdout, sys.stderr = saved
    times.append(time.perf_counter())
    return out.getvalue(), err.getvalue(), max(b - a for a, b in zip(times, times[1:]))


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
    assert bare[0] == "a long wait ..." and bare[-1].startswith("a long wait: over (")
    beats = bare[1:-1]  # at least one heartbeat naming the stage (a loaded machine may add a second)
    assert beats and all(re.fullmatch(r"  \.\.\. a long wait \(\d+ s\)", b) for b in beats), bare
    assert float(re.search(r"\(([\d.]+) s\)", bare[-1]).group(1)) >= HEARTBEAT_S  # the stage's own time, not a bound
    assert left(3, 10, 90.0) == "3 of 10 done in 90 s, about 210 s left" and left(10, 10, 5.0) == "10 of 10 done in 5 s"
