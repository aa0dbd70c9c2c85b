"""Polish a metaheuristic's best with a gradient solver on the same objective.

``objective="pearson"`` minimises the paper's cost ``C = sum_i (1 - rho_i)^2`` (Eq. 7) as the least-squares
problem on the vector ``1 - rho`` (one residual per output channel): Levenberg-Marquardt sees exactly the
paper's cost, with Gauss-Newton curvature instead of BFGS's estimate. ``objective="pem"`` minimises the
prediction-error sum of squares of :func:`jaxheli.optim.pem.pem`. Bounds hold as in PEM
(clipped simulation plus a penalty outside the box). The answer is never worse than the start on the objective polished: where the
solver does not improve it, the start comes back unchanged.
"""

from __future__ import annotations

from typing import Any

from .._types import ArrayLike, Float
from ..bounds import Free
from ..data.flight import FlightData
from ..problem import Problem
from .pem import Objective, PEMResult, Solver, fit, fitted_problem


def polish(
    theta0: Float[ArrayLike, "40"],
    data: FlightData | Problem,
    *,
    objective: Objective = "pearson",
    solver: Solver = "lm",
    max_steps: int = 100,
    free: Free = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    **settings: Any,
) -> PEMResult:
    """Refine ``theta0[40]`` on a record under the metaheuristic's simulation settings.

    ``data`` is the metaheuristic's :class:`~jaxheli.problem.Problem`, or a flight with
    :class:`~jaxheli.problem.Settings` fields in ``settings`` (default: the paper's simulation, one open-loop
    run from rest, ZOH; pass the ``segment``, ``x0``, ``hold`` and ``outputs`` the metaheuristic used so the
    objective is the same; ``lower``/``upper`` the box). ``cost_start`` / ``cost`` of the result are the paper's
    cost of that simulation before and after; ``rss_start`` / ``rss`` the prediction-error sum of squares. The
    guard "never worse" applies to the objective polished (the paper's cost for ``"pearson"``, the sum of
    squares for ``"pem"``). ``solver``, ``max_steps``, ``free``, ``rtol``, ``atol`` as in
    :func:`jaxheli.optim.pem.pem`.
    """
    if objective not in ("pearson", "pem"):
        raise ValueError(f"polish: objective must be 'pearson' or 'pem', got {objective!r}")
    return fit(fitted_problem(data, **settings), theta0, objective, solver, max_steps, free, rtol, atol)
