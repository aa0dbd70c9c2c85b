"""Polish a metaheuristic's best with a gradient solver.

``objective="output-error"`` (the default) minimises the normalised output error with the initial state
estimated and restarts only where the model is unstable (:func:`jaxheli.optim.output_error.output_error`): gains
and offsets are identified, which the paper's Pearson cost cannot see. ``objective="pearson"`` minimises the
paper's cost ``C = sum_i (1 - rho_i)^2`` (Eq. 7) as the least-squares problem on the vector ``1 - rho`` (one
residual per output channel): Levenberg-Marquardt sees exactly the paper's cost (the paper's pure pipeline).
``objective="pem"`` minimises the prediction-error sum of squares of :func:`jaxheli.optim.pem.pem` under the
given simulation settings as they are. Bounds hold as in PEM (a penalty past the box, steps within a margin of
it). The answer is never worse than the start on the objective polished: where the solver does not improve it,
the start comes back unchanged.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from .._types import ArrayLike, Float
from ..bounds import Free
from ..data.flight import FlightData
from ..problem import Problem
from .output_error import output_error
from .pem import PEMResult, Solver, fit, fitted_problem
from .prior import Prior

PolishObjective = Literal["output-error", "pearson", "pem"]
POLISH_OBJECTIVES: tuple[str, ...] = ("output-error", "pearson", "pem")


POLISH_RTOL = 1e-6
"""Relative tolerance of the polish's Cauchy termination (a step below it of every unit coordinate, i.e. of the box's
width, and a residual change below it): 1e-6 of a bound's width is far inside any parameter's standard error, and
stops earlier than 1e-8 with the same sums of squares to six digits."""


def polish(
    theta0: Float[ArrayLike, "*starts 40"],
    data: FlightData | Problem,
    *,
    objective: PolishObjective = "output-error",
    solver: Solver = "lm",
    max_steps: int = 100,
    rounds: int = 4,
    free: Free = None,
    rtol: float = POLISH_RTOL,
    atol: float = 1e-8,
    prior: Prior | None = None,
    final: float | None = None,
    stop: int | None = None,
    **settings: Any,
) -> PEMResult:
    """Refine ``theta0[40]``, or the best of several starts ``theta0[S, 40]``, on a record (``"output-error"``
    solves every start in its first round and continues the best, :func:`~jaxheli.optim.output_error.output_error`;
    the other objectives polish each start and keep the lowest objective).

    ``data`` is the metaheuristic's :class:`~jaxheli.problem.Problem`, or a flight with
    :class:`~jaxheli.problem.Settings` fields in ``settings`` (default: the paper's simulation, one open-loop
    run from rest, ZOH; ``lower``/``upper`` the box). For ``"pearson"`` and ``"pem"`` pass the ``segment``,
    ``x0``, ``hold`` and ``outputs`` the metaheuristic used so the objective is the same; ``"output-error"``
    keeps the channels, hold, g and box and chooses restarts and initial state itself (``rounds`` rounds of
    ``max_steps`` steps). ``cost_start`` / ``cost`` of the result are the paper's cost of the simulation
    polished before and after; ``rss_start`` / ``rss`` the normalised output-error sum of squares. ``solver``,
    ``max_steps``, ``free``, ``atol``, ``prior`` (a Gaussian prior's residuals appended,
    :mod:`jaxheli.optim.prior`) as in :func:`jaxheli.optim.pem.pem`, ``rtol`` (default :data:`POLISH_RTOL`) too;
    ``final`` and ``stop`` (the output error's last run length, s, and the round it stops after, e.g. as
    :func:`~jaxheli.optim.cross_validate.cross_validate` chose them) as in
    :func:`~jaxheli.optim.output_error.output_error`.
    """
    if objective not in POLISH_OBJECTIVES:
        raise ValueError(f"polish: objective must be one of {POLISH_OBJECTIVES}, got {objective!r}")
    problem = fitted_problem(data, **settings)
    if objective == "output-error":
        return output_error(problem, theta0, rounds=rounds, solver=solver, max_steps=max_steps, free=free,
                            rtol=rtol, atol=atol, prior=prior, final=final, stop=stop)
    starts = np.asarray(theta0, dtype=np.float64).reshape(-1, np.shape(theta0)[-1])
    fits = [fit(problem, start, objective, solver, max_steps, free, rtol, atol, prior) for start in starts]
    return min(fits, key=lambda res: res.cost if objective == "pearson" else res.rss)
