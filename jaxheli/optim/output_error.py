"""Output-error fit: least squares on normalised output errors, every run started from its least-squares state.

The paper's Pearson cost is blind to gain and offset, so a model fitted on it alone can have the flight's shapes
at a third of its amplitude. This fit minimises ``sum_i sum_t ((y_i - m_i) / std(m_i))^2``, PEM's normalised
residuals (:func:`jaxheli.optim.pem.fit` with ``objective="pem"``), i.e. ``N`` times the sum over channels of
:func:`jaxheli.cost.nmse`, where the simulation starts every run from the state that best explains its outputs
(``x0="estimated"``, :mod:`jaxheli.sim.shooting`: the initial states are eliminated by variable projection, so
neither a guessed start nor the sensors' noise in a measured restart enters the errors). That is the
maximum-likelihood output error for white measurement noise, also for an open-loop-unstable model:

- runs: one over each record when the model is stable or its fastest unstable mode grows at most :data:`GROWTH`
  times over the record; otherwise a restart every ``segment`` s, the longest of :data:`SEGMENTS` over which it
  does (an unstable candidate still gives bounded errors). Mettler's R-50 doubles its phugoid in 2.3 s: over
  80 s from one estimated state the truth's own errors are 10^7 times the noise, over 5 s runs they are the noise;
- rounds: each round chooses the runs at the current parameters and solves. The first rounds cap the runs at the
  lengths of :data:`LADDER` (short runs first: a poor start's errors cannot build up over a long open-loop run);
  the fit ends when an uncapped round converges, or after ``rounds`` rounds. ``final`` caps the runs of every
  round (the ladder's caps below it first): the run length that
  :func:`~jaxheli.optim.cross_validate.cross_validate` chooses.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import jax
import numpy as np

from .._progress import note
from .._types import Array, ArrayLike, Float
from .._xla import quick_jit
from ..bounds import Free
from ..model import build_ab
from ..problem import Problem, Records, parts
from .pem import PEMResult, Solver, fit
from .prior import Prior

GROWTH = 1e3
"""Largest growth of the fastest unstable mode over one simulated run of the rounds after the ladder."""

SEGMENTS: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0, 40.0)
"""Restart intervals, s, an unstable model is simulated with (all share one compiled solver: the run length is a
run-time value, the number of runs bounded by that of runs of :data:`jaxheli.sim.shooting.SHORTEST_RUN_S`, 1 s)."""

LADDER: tuple[float, ...] = (5.0, 20.0)
"""Caps, s, on the run length of the first rounds: from a population optimiser's start, runs over the whole record
can stall far above the truth's sum of squares, where 5-s, then 20-s, then whole-record runs reach it."""


RACE_STEPS = 20
"""Steps every start of the first round takes before the rest of the round goes to the one of least sum of squares
alone (the leader after this many steps is, in practice, the leader after a full round)."""


def restart_interval(
    theta: Float[ArrayLike, "40"], g: float, duration: float, growth: float = GROWTH
) -> float | None:
    """Restart interval, s, for ``theta`` on a ``duration``-s record: ``None`` (one run) when the fastest
    unstable mode grows at most ``growth`` times over the record, else the longest of :data:`SEGMENTS` over
    which it does (the shortest when none does, or when ``theta`` is not finite)."""
    A = np.asarray(_state_matrix(np.asarray(theta, dtype=np.float64), g))
    if not np.all(np.isfinite(A)):
        return SEGMENTS[0]
    rate = float(np.max(np.linalg.eigvals(A).real))
    horizon = np.log(growth) / rate if rate > 0 else np.inf
    if horizon >= duration:
        return None
    fitting = [s for s in SEGMENTS if s <= horizon]
    return fitting[-1] if fitting else SEGMENTS[0]


@functools.partial(quick_jit, jit=jax.jit)
def _state_matrix(theta: Float[Array, "40"], g: float) -> Float[Array, "13 13"]:
    """The hover model's ``A`` (one small program, instead of ``build_ab``'s op-by-op dispatch)."""
    return build_ab(theta, g)[0]


def output_error_problem(
    problem: Problem | Records, theta: Float[ArrayLike, "40"], growth: float = GROWTH, final: float | None = None
) -> Problem | Records:
    """``problem`` as the output-error fit simulates it at ``theta``: restarts from :func:`restart_interval`
    (``growth``), at most ``final`` s apart where given, every run from its least-squares initial state (each
    record's own, for :class:`~jaxheli.problem.Records`)."""
    theta = np.asarray(theta, dtype=np.float64)
    if isinstance(problem, Records):
        return Records(tuple(output_error_problem(part, theta, growth, final) for part in problem.parts))
    caps = [s for s in (restart_interval(theta, problem.settings.g, problem.n_samples * problem.dt, growth), final)
            if s is not None]
    return in_runs(problem, min(caps, default=None))


def in_runs(problem: Problem | Records, segment: float | None) -> Problem | Records:
    """``problem`` simulated in runs of ``segment`` s (one run where the record is not longer), each from its
    least-squares initial state."""
    if isinstance(problem, Records):
        return Records(tuple(in_runs(part, segment) for part in problem.parts))
    if segment is not None and segment >= (problem.n_samples - 1) * problem.dt:
        segment = None
    return problem.variant(segment=segment, x0="estimated", simulator="scan")


def output_error(
    problem: Problem | Records,
    start: Float[ArrayLike, "40"],
    *,
    rounds: int = 4,
    solver: Solver = "lm",
    max_steps: int = 100,
    free: Free = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    prior: Prior | None = None,
    final: float | None = None,
    stop: int | None = None,
) -> PEMResult:
    """Fit ``problem``'s record by output error from ``start[40]`` in at most ``rounds`` rounds (see the module).

    ``start`` may hold several starts ``[S, 40]``: each is solved for :data:`RACE_STEPS` steps in the first round
    (the same runs and compiled solver for all, when the ladder applies), and the round goes on from the lowest sum
    of squares alone.

    ``problem``'s scored channels, hold, g and box apply (its restarts and initial states are replaced; each
    record of a :class:`~jaxheli.problem.Records` gets its own); ``solver``, ``max_steps`` (per round), ``free``,
    ``rtol``, ``atol``, ``prior`` as in :func:`jaxheli.optim.pem.pem`; ``final`` (s) caps every run (default: none;
    the ladder keeps its caps below it); ``stop`` ends the fit after that many of the ``rounds`` rounds (the
    schedule stays that of ``rounds``). The result's ``rss_start`` / ``cost_start`` are those
    of the first round's simulation, ``rss`` / ``cost`` those of the last; ``settings["rounds"]`` lists each
    round's restart intervals, sums of squares, steps, solver result and parameters at its end. Never worse than
    the start on any round's objective.
    """
    if rounds < 1:
        raise ValueError(f"output_error: rounds must be >= 1, got {rounds}")
    if final is not None and not final > 0:
        raise ValueError(f"output_error: final run length must be positive, got {final} s")
    caps = tuple(c for c in LADDER if final is None or c < final)
    thetas = np.asarray(start, dtype=np.float64).reshape(-1, np.shape(start)[-1])
    results: list[PEMResult] = []
    history: list[dict[str, Any]] = []
    for k in range(rounds if stop is None else min(stop, rounds)):
        ladder = k < len(caps) and k < rounds - 1
        runs = in_runs(problem, caps[k]) if ladder else None
        race = len(thetas) > 1 and max_steps > RACE_STEPS
        tried = []
        for theta in thetas:
            chosen = runs if ladder else output_error_problem(problem, theta, final=final)
            steps = RACE_STEPS if race else max_steps
            tried.append((fit(chosen, theta, "pem", solver, steps, free, rtol, atol, prior, max_steps), chosen))
        res, chosen = min(tried, key=lambda pair: pair[0].rss)
        if race and not res.success:
            more = fit(chosen, res.theta, "pem", solver, max_steps - RACE_STEPS, free, rtol, atol, prior, max_steps)
            res = dataclasses.replace(more, theta_start=res.theta_start, cost_start=res.cost_start,
                                      rss_start=res.rss_start, n_steps=res.n_steps + more.n_steps)
        history.append({"segment_s": [p.settings.segment for p in parts(chosen)], "ladder": ladder,
                        "rss_start": res.rss_start, "rss": res.rss, "n_steps": res.n_steps, "result": res.result,
                        "theta": res.theta.tolist(),
                        **({"starts_rss": [r.rss for r, _ in tried]} if len(tried) > 1 else {})})
        lengths = dict.fromkeys("whole record" if r is None else f"{r:g} s" for r in history[-1]["segment_s"])
        note(f"  round {k + 1} of at most {rounds}: runs of {', '.join(lengths)}, RSS {res.rss_start:.6g} -> "
             f"{res.rss:.6g} in {res.n_steps} steps ({res.result})"
             + (f"; starts' RSS {', '.join(f'{r.rss:.6g}' for r, _ in tried)}" if len(tried) > 1 else ""))
        results.append(res)
        thetas = res.theta[None]
        if res.success and not ladder:
            break
    first, final = results[0], results[-1]
    settings = {**final.settings, "objective": "output-error", "rounds": history}
    return dataclasses.replace(final, theta_start=first.theta_start, cost_start=first.cost_start,
                               rss_start=first.rss_start, n_steps=sum(r.n_steps for r in results),
                               settings=settings)
