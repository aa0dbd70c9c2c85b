"""One CPU core per process, for runs that split work over processes (blind trials).

XLA's CPU runtime sizes its thread pools when JAX is imported, to the cores the process may use then, and idle
pool threads spin before they sleep. Two JAX processes sharing two cores, or one moved onto a single core after
importing JAX, lose most of their time to those spinning threads (a process moved after importing JAX ran
about 15 times slower than one started on its core). A process must therefore *start* on its core:
:func:`on_core` sets the core of the calling thread, and processes started inside it inherit it.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator


def cores() -> list[int]:
    """The cores this thread may run on, sorted (empty where the platform cannot pin processes)."""
    return sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_setaffinity") else []


@contextlib.contextmanager
def on_core(core: int | None) -> Iterator[None]:
    """Run the calling thread on ``core`` inside the block (``None``: leave it as it is), so that processes
    started there begin on that core; the thread's own cores come back on exit."""
    if core is None:
        yield
        return
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {core})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)
