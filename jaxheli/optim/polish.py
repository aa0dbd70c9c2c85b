"""Polish a metaheuristic's best with a gradient solver on the same objective.

``objective="pearson"`` minimises the paper's cost ``C = sum_i (1 - rho_i)^2`` (Eq. 7) as the least-squares
problem on the vector ``1 - rho`` (one residual per output channel): Levenberg-Marquardt sees exactly the
paper's cost, with Gauss-Newton curvature instead of BFGS's estimate. ``objective="pem"`` minimises the
prediction-error sum of squares of :func:`jaxheli.optim.pem.pem`. Bounds hold as in PEM
(clipped simulation plus a penalty outside the box). The answer is never worse than the start on the objective polished: where the
solver does not improve it, the start comes back unchanged.
"""

from __future__ import annotations

from .._types import ArrayLike, Float
from ..sim.discretize import Hold
from ..data.flight import FlightData
from ..model import G_SI
from ..sim.simulate import InitialState
from ._box import Free
from .pem import Objective, PEMResult, Solver, _fit


def polish(
    theta0: Float[ArrayLike, "40"],
    flight: FlightData,
    *,
    objective: Objective = "pearson",
    outputs: tuple[str, ...] | list[str] | None = None,
    segment: float | None = None,
    hold: Hold = "zoh",
    x0: InitialState = "zero",
    g: float = G_SI,
    solver: Solver = "lm",
    max_steps: int = 100,
    free: Free = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
) -> PEMResult:
    """Refine ``theta0[40]`` on ``flight`` under the metaheuristic's simulation settings.

    The defaults are the paper's simulation (one open-loop run from rest, ZOH); pass the ``segment``,
    ``x0``, ``hold`` and ``outputs`` the metaheuristic used so the objective is the same. ``cost_start`` /
    ``cost`` of the result are the paper's cost of that simulation before and after; ``rss_start`` /
    ``rss`` the prediction-error sum of squares. The guard "never worse" applies to the objective
    polished (the paper's cost for ``"pearson"``, the sum of squares for ``"pem"``). ``solver``,
    ``max_steps``, ``free``, ``rtol``, ``atol`` as in :func:`jaxheli.optim.pem.pem`.
    """
    if objective not in ("pearson", "pem"):
        raise ValueError(f"polish: objective must be 'pearson' or 'pem', got {objective!r}")
    return _fit(flight, theta0, objective, outputs, segment, hold, x0, g, solver, max_steps, free, rtol, atol)
