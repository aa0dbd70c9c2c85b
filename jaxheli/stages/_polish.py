"""The gradient polish as a stage: every trial refined by Levenberg-Marquardt on the polish objective, its run
length and stopping round chosen by cross-validation on left-out windows where asked."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from .._progress import note, stage
from .._types import Float
from ..data.flight import FlightData
from ..evaluate import search_cost_of
from ..model import PARAM_NAMES
from ..optim.cross_validate import CrossValidation, check_windows, cross_validate
from ..optim.output_error import output_error_problem
from ..optim.pem import PEMResult
from ..optim.polish import POLISH_OBJECTIVES, PolishObjective, polish
from ..problem import Problem, Records
from ._prior import PriorModel, belief, prior_settings
from ._stage import Record, Stage, Starts, Task

ROUNDS = 4
"""Default most rounds of the output-error polish."""


class Polish(Stage):
    """:func:`~jaxheli.optim.polish.polish` of every trial (with its second start where the previous stage left one:
    the output-error polish's first round tries both); each trial's cost becomes its polished objective (the
    paper's cost for ``"pearson"``, else the normalised sum of squares per sample).

    Attributes:
        objective: ``"output-error"`` (normalised output errors, every run from its least-squares state, runs
            shortened where the model is unstable, :mod:`jaxheli.optim.output_error`), ``"pearson"`` (the paper's
            cost: after a search on it, the paper's pure pipeline) or ``"pem"``.
        steps: Levenberg-Marquardt steps (per round for output error).
        rounds: the most rounds (output error only; default :data:`ROUNDS`).
        cv_windows: output error on one flight: choose the last run length and the stopping round by
            leave-one-window-out cross-validation over that many windows of the flight
            (:func:`~jaxheli.optim.cross_validate.cross_validate`, the folds from the polish's own starts); 0: the
            full schedule.
        prior, prior_sd: a prior model (:data:`~jaxheli.stages.PriorModel`) and its standard deviation in percent
            of each value (default :data:`~jaxheli.stages.PRIOR_SD`, :mod:`jaxheli.optim.prior`), whose residuals join the polish's.
    """

    FIRST: ClassVar[bool | None] = False

    objective: PolishObjective = "output-error"
    steps: int = 100
    rounds: int | None = None
    cv_windows: int = 0
    prior: PriorModel | None = None
    prior_sd: float | None = None

    def __check_init__(self) -> None:
        if self.objective not in POLISH_OBJECTIVES:
            raise ValueError(f"Polish: objective must be one of {POLISH_OBJECTIVES}, got {self.objective!r}")
        if self.objective != "output-error" and (self.rounds is not None or self.cv_windows):
            raise ValueError(f"Polish: rounds and cv_windows need the output-error objective, got {self.objective!r}")
        belief(self.prior, self.prior_sd)

    @property
    def name(self) -> str:
        return "polish"

    def check(self, task: Task) -> None:
        if self.cv_windows:
            if not isinstance(task.data, FlightData):
                raise ValueError("Polish: cv_windows needs one training flight (not several, not a Problem), got "
                                 f"{type(task.data).__name__}")
            check_windows(task.data, self.cv_windows)

    def errors_problem(self, problem: Problem | Records, params: Float[np.ndarray, "40"]) -> Problem | Records:
        return output_error_problem(problem, params) if self.objective == "output-error" else problem

    def __call__(self, task: Task, starts: Starts | None) -> tuple[Starts, Record]:
        problem, prior, rounds = task.problem, belief(self.prior, self.prior_sd), self.rounds or ROUNDS
        first = starts.params if starts.also is None else np.stack([starts.params, starts.also], axis=1)
        chosen = None if not self.cv_windows else self._cross_validation(task, first[starts.best], prior)
        schedule = {} if chosen is None else {"final": chosen.final, "stop": chosen.rounds}
        polished = []
        for k, th in enumerate(first):
            with stage(f"polish of trial {k + 1} of {len(first)} on the {self.objective} objective, "
                       + (f"up to {rounds} rounds of " if self.objective == "output-error" else "")
                       + f"{self.steps} LM steps") as now:
                polished.append(polish(th, problem, objective=self.objective, max_steps=self.steps, rounds=rounds,
                                       prior=prior, **schedule))
                now.outcome = f"{polished[-1].n_steps} steps"
        costs = np.array([p.cost if self.objective == "pearson" else p.rss / problem.n_samples for p in polished])
        found = Starts(np.stack([p.theta for p in polished]), costs)
        return found, Record(polish=self._summary(problem, starts, polished, found, chosen))

    def _cross_validation(self, task: Task, first: np.ndarray, prior: Any) -> CrossValidation:
        """The run length and stopping round chosen on the flight's windows, from the best trial's starts."""
        found = cross_validate(task.data, task.problem.settings, first, self.cv_windows, rounds=self.rounds or ROUNDS,
                               max_steps=self.steps, prior=prior)
        note(f"cross-validation: {found.describe()}")
        return found

    def _summary(self, problem: Problem | Records, starts: Starts, polished: list[PEMResult], found: Starts,
                 chosen: CrossValidation | None) -> dict[str, Any]:
        """``IdentificationResult.polish``: the best start and the best answer on the search cost and on the
        polish's objective, each trial's steps, and the best answer's rounds."""
        before, after = starts.best, found.best
        n = problem.n_samples
        search_costs = [search_cost_of(theta, problem) for theta in (starts.params[before], polished[after].theta)]
        return {
            "objective": self.objective,
            "params_before": dict(zip(PARAM_NAMES, map(float, starts.params[before]))),
            "cost_before": float(search_costs[0]),
            "cost_after": float(search_costs[1]),
            "objective_before": float(polished[before].cost_start if self.objective == "pearson"
                                      else polished[before].rss_start / n),
            "objective_after": float(found.costs[after]),
            "steps": [p.n_steps for p in polished],
            "rounds": polished[after].settings.get("rounds"),
            "objective_rounds": objective_rounds(polished[after], self.objective, n),
            "cross_validation": None if chosen is None else chosen.to_json(),
        }

    def refit(self) -> dict[str, Any]:
        """How a structure determination repeats this fit (:func:`~jaxheli.optim.structure.determine_structure`);
        ``ValueError`` for the Pearson objective, which is no least-squares fit of the outputs."""
        if self.objective == "pearson":
            raise ValueError("Structure: needs a least-squares fit to repeat: PEM, or a polish on 'output-error' or "
                             "'pem' (got the polish on 'pearson')")
        return {"local_fit": self.objective, "max_steps": self.steps, "prior": belief(self.prior, self.prior_sd)}

    def settings(self) -> dict[str, Any]:
        return {"polish_objective": self.objective, "polish_steps": self.steps, "polish_rounds": self.rounds or ROUNDS,
                "cv_windows": self.cv_windows, **prior_settings(self.prior, self.prior_sd)}


def objective_rounds(res: PEMResult, objective: PolishObjective, n_samples: int) -> list[list[float]]:
    """``[start, end]`` of the polish's objective in each of its rounds (one for ``"pearson"`` and ``"pem"``), on
    the scale of ``objective_before`` / ``objective_after``; the output-error polish's first rounds score shortened
    runs, so a round may start above where the one before ended."""
    if objective == "pearson":
        return [[float(res.cost_start), float(res.cost)]]
    rounds = res.settings.get("rounds") or [{"rss_start": res.rss_start, "rss": res.rss}]
    return [[float(r["rss_start"]) / n_samples, float(r["rss"]) / n_samples] for r in rounds]
