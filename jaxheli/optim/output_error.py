"""Output-error fit: least squares on normalised output errors, initial state estimated, restarts only where the
model is unstable.

The paper's Pearson cost is blind to gain and offset, so a model fitted on it alone can have the flight's shapes
at a third of its amplitude. This fit minimises ``sum_i sum_t ((y_i - m_i) / std(m_i))^2``, PEM's normalised
residuals (:func:`jaxheli.optim.pem.fit` with ``objective="pem"``), i.e. ``N`` times the sum over channels of
:func:`jaxheli.cost.nmse`, in rounds; each chooses its simulation at the current parameters, then solves:

- restarts: one open-loop run over each record when the model is stable or its fastest unstable mode grows at
  most ``growth`` times over the record; otherwise a restart from the measured states every ``segment`` s, the
  longest of :data:`SEGMENTS` over which that mode grows at most ``growth`` times (an unstable candidate still
  gives bounded residuals, and a restart keeps the slow unstable mode from dominating a poor model's errors);
- initial state: the least-squares estimate (:func:`jaxheli.sim.initial_state.estimate_x0`) over the first
  run, each record's own.

The rounds before the last restart where the mode grows more than :data:`GROWTH` times and hold the initial
state (far from the optimum a free initial state lets the fit wander). The last round is the
maximum-likelihood output error for measurement noise: one run per record unless the mode grows more than
:data:`FINAL_GROWTH` times over it, the initial states fitted with the parameters. On the default flight (80 s,
Table 2 truth) three rounds of 30 steps from a 100-generation IWO reach the truth's fit % on every channel (20
steps do not), where one round of 100 steps stalls in a valley of the rotor parameters. Every distinct segment length compiles the solver once.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import jax
import numpy as np

from .._types import Array, ArrayLike, Float
from .._xla import QUICK_COMPILE
from ..bounds import Free
from ..model import build_ab
from ..problem import Problem, Records, parts
from ..sim.initial_state import estimate_x0
from .pem import PEMResult, Solver, fit

GROWTH = 10.0
"""Largest growth of the fastest unstable mode over one simulated run in the rounds before the last."""

FINAL_GROWTH = 1e3
"""Largest growth of the fastest unstable mode over one simulated run in the last round."""

SEGMENTS: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0, 40.0)
"""Restart intervals, s, an unstable model is simulated with (few values: each compiles the solver once)."""


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


@functools.partial(jax.jit, compiler_options=QUICK_COMPILE)
def _state_matrix(theta: Float[Array, "40"], g: float) -> Float[Array, "13 13"]:
    """The hover model's ``A`` (one small program, instead of ``build_ab``'s op-by-op dispatch)."""
    return build_ab(theta, g)[0]


def output_error_problem(
    problem: Problem | Records, theta: Float[ArrayLike, "40"], growth: float = FINAL_GROWTH
) -> Problem | Records:
    """``problem`` as the output-error fit simulates it at ``theta``: restarts from :func:`restart_interval`
    (``growth``; default: the last round's), the initial state estimated over the first run (each record's own,
    for :class:`~jaxheli.problem.Records`)."""
    theta = np.asarray(theta, dtype=np.float64)
    if isinstance(problem, Records):
        return Records(tuple(output_error_problem(part, theta, growth) for part in problem.parts))
    segment = restart_interval(theta, problem.settings.g, problem.n_samples * problem.dt, growth)
    chosen = problem.variant(segment=segment, x0="zero")
    return chosen.start_from(estimate_x0(theta, chosen, horizon=segment))


def output_error(
    problem: Problem | Records,
    start: Float[ArrayLike, "40"],
    *,
    rounds: int = 3,
    solver: Solver = "lm",
    max_steps: int = 30,
    free: Free = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
) -> PEMResult:
    """Fit ``problem``'s record by output error from ``start[40]`` in ``rounds`` rounds (see the module).

    ``problem``'s scored channels, hold, g and box apply (its restarts and initial state are replaced; each
    record of a :class:`~jaxheli.problem.Records` gets its own); ``solver``, ``max_steps`` (per round), ``free``,
    ``rtol``, ``atol`` as in :func:`jaxheli.optim.pem.pem`. The result's ``rss_start`` / ``cost_start`` are those
    of the first round's simulation, ``rss`` / ``cost`` / ``x0`` those of the last; ``settings["rounds"]`` lists
    each round's restart intervals, initial states and sums of squares. Never worse than the start on any
    round's objective.
    """
    if rounds < 1:
        raise ValueError(f"output_error: rounds must be >= 1, got {rounds}")
    theta = np.asarray(start, dtype=np.float64)
    results: list[PEMResult] = []
    history: list[dict[str, Any]] = []
    for k in range(rounds):
        last = k == rounds - 1
        chosen = output_error_problem(problem, theta, FINAL_GROWTH if last else GROWTH)
        res = fit(chosen, theta, "pem", solver, max_steps, free, rtol, atol, fit_x0=last, with_x0=True)
        history.append({"segment_s": [p.settings.segment for p in parts(chosen)], "x0": res.x0.tolist(),
                        "x0_fitted": last, "rss_start": res.rss_start, "rss": res.rss, "n_steps": res.n_steps,
                        "result": res.result})
        results.append(res)
        theta = res.theta
    first, final = results[0], results[-1]
    settings = {**final.settings, "objective": "output-error", "rounds": history}
    return dataclasses.replace(final, theta_start=first.theta_start, cost_start=first.cost_start,
                               rss_start=first.rss_start, n_steps=sum(r.n_steps for r in results),
                               settings=settings)
