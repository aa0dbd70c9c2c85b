"""The prediction-error method as a stage: one least-squares fit per trial of a predictor that restarts from the
measured states."""

from __future__ import annotations

from typing import Any, ClassVar

import jax
import numpy as np

from .._types import Float
from ..optim.pem import pem
from ..problem import Problem, Records
from ._prior import PriorModel, belief, prior_settings
from ._stage import Record, Stage, Starts, Task


class PEM(Stage):
    """PEM (:func:`jaxheli.optim.pem.pem`) from ``start`` (default: the middle of the box), and for each further
    trial from a point drawn in the box from ``PRNGKey(seed)``.

    Attributes:
        start: ``[40]`` the first trial's start.
        segment: the predictor's restart interval, s (keeps unstable candidates usable).
        steps: Levenberg-Marquardt steps of each fit (and of each re-fit of a structure determination).
        prior, prior_sd: a prior model (:data:`~jaxheli.stages.PriorModel`) and its standard deviation in percent
            of each value (default :data:`~jaxheli.stages.PRIOR_SD`, :mod:`jaxheli.optim.prior`), whose residuals join PEM's.
    """

    FIRST: ClassVar[bool | None] = True

    start: Float[np.ndarray, "40"] | None = None
    segment: float = 5.0
    steps: int = 200
    prior: PriorModel | None = None
    prior_sd: float | None = None

    @property
    def name(self) -> str:
        return "pem"

    def __check_init__(self) -> None:
        belief(self.prior, self.prior_sd)

    def fitted(self, problem: Problem | Records) -> Problem | Records:
        return problem.variant(segment=self.segment, x0="measured")

    def __call__(self, task: Task, starts: Starts | None) -> tuple[Starts, Record]:
        problem, trials = self.fitted(task.problem), task.trials
        first = problem.bounds.midpoint() if self.start is None else np.asarray(self.start, dtype=np.float64)
        key = jax.random.PRNGKey(task.seed)
        drawn = [problem.bounds.uniform(k, 1)[0] for k in jax.random.split(key, trials - 1)] if trials > 1 else []
        prior = belief(self.prior, self.prior_sd)
        fits = [pem(problem, start=s, max_steps=self.steps, prior=prior) for s in [first, *drawn]]
        converged = [{"steps": f.n_steps, "result": f.result, "converged": f.success} for f in fits]
        return Starts(np.stack([f.theta for f in fits]), np.array([f.cost for f in fits])), Record(convergence=converged)

    def refit(self) -> dict[str, Any]:
        """How a structure determination repeats this fit (:func:`~jaxheli.optim.structure.determine_structure`)."""
        return {"local_fit": "pem", "max_steps": self.steps, "prior": belief(self.prior, self.prior_sd)}

    def settings(self) -> dict[str, Any]:
        return {"pem_segment": self.segment, **prior_settings(self.prior, self.prior_sd)}
