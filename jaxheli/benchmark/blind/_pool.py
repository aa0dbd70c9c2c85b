"""Blind trials run one after another, or in a pool of processes each started on a core of its own, with a progress
line per trial and a callback after each."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

import jax

from ..._affinity import cores, on_core
from ..._progress import left, note, stage
from ._trial import Trial, run_trial


def run_blind(
    trials: Sequence[Trial | tuple[str, int]],
    *,
    on_trial: Callable[[list[dict[str, Any]]], None] | None = None,
    workers: int = 1,
    **options: Any,
) -> list[dict[str, Any]]:
    """Diagnose each trial (a :class:`Trial` or ``(kind, seed)``) blind (:func:`run_trial` with ``options``);
    one record per trial, in the order of ``trials``, with the trial's base method (``trial_base``). ``workers > 1``
    runs trials in that many processes (each a trial at a time, in float64, each started on a core of its own when
    the machine has that many, :func:`_worker_cores`). A progress line reports each trial, with the time left
    (:func:`jaxheli.reporting`; in one process its stages too), and ``on_trial(records_so_far)`` runs after each,
    e.g. to save (records finished so far, in the order of ``trials``)."""
    done: dict[int, dict[str, Any]] = {}

    def finished(i: int, record: dict[str, Any]) -> None:
        done[i] = {**record, "trial_base": trials[i].base}
        if on_trial is not None:
            on_trial([done[j] for j in sorted(done)])

    trials = [Trial(*t) for t in trials]
    start = time.perf_counter()
    note(f"blind check: {len(trials)} trial(s) in {max(workers, 1)} process(es); each process's first trial "
         "compiles the solvers")
    if workers <= 1:
        for i, (kind, seed, base) in enumerate(trials):
            with stage(f"trial {i + 1} of {len(trials)}: {kind}, seed {seed}, {base} base model") as now:
                record = run_trial(kind, seed, base=base, **options)
                now.outcome = _outcome(record)
            finished(i, record)
            note(f"trials: {left(len(done), len(trials), time.perf_counter() - start)}")
    else:
        todo = iter(enumerate(trials))
        running: dict[Future, tuple[int, ProcessPoolExecutor]] = {}

        def feed(pool: ProcessPoolExecutor) -> None:
            trial = next(todo, None)
            if trial is not None:
                i, (kind, seed, base) = trial
                running[pool.submit(run_trial, kind, seed, base=base, **options)] = (i, pool)

        with contextlib.ExitStack() as stack:
            with stage(f"starting {workers} trial processes"):
                for core in _worker_cores(workers):
                    feed(stack.enter_context(_process_on(core)))
            with stage(f"{len(trials)} trials in {len(running)} processes"):
                while running:
                    for job in wait(running, return_when=FIRST_COMPLETED)[0]:
                        i, pool = running.pop(job)
                        finished(i, job.result())
                        kind, seed, base = trials[i]
                        note(f"trial {i + 1} of {len(trials)} ({kind}, seed {seed}, {base} base model): "
                             f"{_outcome(done[i])}; {left(len(done), len(trials), time.perf_counter() - start)}")
                        feed(pool)
    return [done[i] for i in range(len(trials))]


def _outcome(record: dict[str, Any]) -> str:
    """A finished trial in words: the effect it named and whether that is right."""
    return f"named {record['top']} ({'right' if record['correct'] else 'wrong'})"


def _worker_cores(workers: int) -> list[int | None]:
    """A core for each of ``workers`` trial processes, or ``None`` for each (not pinned) when the machine has fewer
    cores than that: unpinned JAX processes that share cores slow each other down (:mod:`jaxheli._affinity`)."""
    usable = cores()
    return usable[:workers] if len(usable) >= workers else [None] * workers


def _process_on(core: int | None) -> ProcessPoolExecutor:
    """A one-process pool whose process is started (spawned) on ``core`` (:func:`~jaxheli._affinity.on_core`)
    before it imports JAX, in float64, watching this run (:func:`_worker`)."""
    context = multiprocessing.get_context("spawn")
    with on_core(core):
        pool = ProcessPoolExecutor(1, mp_context=context, initializer=_worker, initargs=(os.getpid(),))
        pool.submit(int).result()
    return pool


def _worker(parent: int) -> None:
    """A trial process's set-up: float64, and an exit once ``parent``, the run that spawned it, is gone
    (:func:`_exit_with`)."""
    jax.config.update("jax_enable_x64", True)
    threading.Thread(target=_exit_with, args=(parent,), daemon=True).start()


def _exit_with(parent: int, poll: float = 2.0) -> None:
    """End this process once its parent ``parent`` has ended (checked every ``poll`` s): a run stopped by a signal
    leaves no orphaned worker behind to finish its trial on cores nobody reads it from."""
    while os.getppid() == parent:
        time.sleep(poll)
    os._exit(1)
