"""Progress lines of the long stages (an identification, a diagnosis, a blind check): what a user waiting at the
command line reads, and nothing at all for a library caller.

The library calls :func:`note` for a line and :func:`stage` around anything that may take seconds; both do nothing
unless a caller turned the lines on with :func:`reporting` (the command line does, unless ``--quiet``). Within it,
each line goes to stderr stamped with the seconds since :func:`reporting` began, and a watchdog thread writes
``... STAGE (N s)`` whenever nothing was written for :data:`HEARTBEAT_S`, so no stage, one long compile included,
is silent for longer. Lines go through ``tqdm.write``, so they stay apart from the progress bar of
:func:`jaxheli.optim.run.minimize`, whose moves count as output (:func:`touch`).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from tqdm import tqdm

HEARTBEAT_S = 3.0
"""Longest silence, s, before the watchdog names the stage still running: 3, so that a stage holding the GIL (the
plots) may delay the watchdog's line by up to 2 s and still stay under 5 s of silence (at 4 the plots of a diagnosis
under a loaded suite left 5.1 s)."""


class _Reporter:
    """The lines of one :func:`reporting` block: their clock, the stages open (innermost last) and the watchdog."""

    def __init__(self) -> None:
        self.start = self.last = time.perf_counter()
        self.stages: list[tuple[str, float]] = []
        self.lock = threading.Lock()
        self.done = threading.Event()

    def write(self, message: str) -> None:
        with self.lock:
            self.last = time.perf_counter()
            tqdm.write(f"[{self.last - self.start:7.1f} s] {message}", file=sys.stderr)

    def watch(self) -> None:
        while not self.done.wait(0.2):
            now = time.perf_counter()
            if now - self.last >= HEARTBEAT_S:
                innermost = self.stages[-1:]  # a slice: the main thread may close the stage meanwhile
                label, since = innermost[0] if innermost else ("working", self.last)
                self.write(f"  ... {label} ({now - since:.0f} s)")


_ACTIVE: _Reporter | None = None
"""The :func:`reporting` block in force (a module global, not a context variable: the progress bar's host callback
runs on another thread)."""


@contextmanager
def reporting(on: bool = True) -> Iterator[None]:
    """Within the block, :func:`note` and :func:`stage` write their lines to stderr (``on=False``: the block is
    silent, whatever surrounds it)."""
    global _ACTIVE
    outer, _ACTIVE = _ACTIVE, _Reporter() if on else None
    watchdog = None
    if _ACTIVE is not None:
        watchdog = threading.Thread(target=_ACTIVE.watch, name="jaxheli-progress", daemon=True)
        watchdog.start()
    try:
        yield
    finally:
        if watchdog is not None:
            _ACTIVE.done.set()
            watchdog.join()
        _ACTIVE = outer


def active() -> bool:
    """Whether a :func:`reporting` block is on here (e.g. to turn it on in a process this one starts)."""
    return _ACTIVE is not None


def note(message: str) -> None:
    """Write ``message`` as one progress line, when :func:`reporting` is on."""
    if _ACTIVE is not None:
        _ACTIVE.write(message)


def touch() -> None:
    """Count as output for the watchdog (a progress bar moved)."""
    if _ACTIVE is not None:
        _ACTIVE.last = time.perf_counter()


class Stage:
    """An open :func:`stage`: set ``outcome`` to end its closing line with it."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.outcome = "done"


@contextmanager
def stage(label: str) -> Iterator[Stage]:
    """Note ``label ...`` as the block starts and ``label: OUTCOME (N s)`` as it ends (``OUTCOME``: what the block
    set on the :class:`Stage` it was given, ``done`` by default; nothing when it raised); the watchdog names the
    innermost stage open."""
    opened = Stage(label)
    reporter = _ACTIVE
    if reporter is None:
        yield opened
        return
    start = time.perf_counter()
    reporter.write(f"{label} ...")
    reporter.stages.append((label, start))
    try:
        yield opened
    finally:
        reporter.stages.pop()
    reporter.write(f"{label}: {opened.outcome} ({time.perf_counter() - start:.1f} s)")


def left(done: int, total: int, seconds: float) -> str:
    """``done`` of ``total`` items after ``seconds``, with the time left at that pace (e.g. ``3 of 10 done in
    95 s, about 222 s left``)."""
    text = f"{done} of {total} done in {seconds:.0f} s"
    return text + (f", about {seconds * (total - done) / done:.0f} s left" if 0 < done < total else "")
