"""Model-structure determination as a stage: a least-squares stage (PEM or the polish) run, then its fit repeated
with the parameters the record cannot determine held fixed."""

from __future__ import annotations

from typing import Any

import numpy as np

from .._progress import stage
from .._types import Float
from ..optim.structure import determine_structure
from ..problem import Problem, Records
from ._pem import PEM
from ._polish import Polish
from ._stage import Record, Stage, Starts, Task


class Structure(Stage):
    """``fit``, then :func:`~jaxheli.optim.structure.determine_structure` from its best trial: parameters the
    record cannot determine (unresolved, relative Cramer-Rao bound above 20 %, or the worse of a pair correlated
    above 0.95) are fixed (to ``fit``'s prior value, else 0 or the nearest bound) and ``fit``'s local fit repeated
    with them pinned, until nothing more is fixed. The trials stay ``fit``'s; the answer is the determination's
    (:attr:`Record.structure`).

    Attributes:
        fit: the least-squares stage whose fit is repeated: :class:`PEM`, or :class:`Polish` on ``"output-error"``
            or ``"pem"``.
    """

    fit: PEM | Polish

    def __check_init__(self) -> None:
        if not isinstance(self.fit, (PEM, Polish)):
            raise ValueError(f"Structure: fit must be a PEM or Polish stage, got {type(self.fit).__name__}")
        self.fit.refit()

    @property
    def name(self) -> str:
        return self.fit.name

    def check_place(self, first: bool) -> None:
        self.fit.check_place(first)

    def check(self, task: Task) -> None:
        self.fit.check(task)

    def fitted(self, problem: Problem | Records) -> Problem | Records:
        return self.fit.fitted(problem)

    def errors_problem(self, problem: Problem | Records, params: Float[np.ndarray, "40"]) -> Problem | Records:
        return self.fit.errors_problem(problem, params)

    def __call__(self, task: Task, starts: Starts | None) -> tuple[Starts, Record]:
        found, record = self.fit(task, starts)
        with stage("model-structure determination: fix poorly determined parameters and re-fit") as now:
            structure = determine_structure(self.fit.fitted(task.problem), found.params[found.best],
                                            **self.fit.refit())
            now.outcome = f"{len(structure.fixed_dict())} fixed"
        return found, record.merge(Record(structure=structure))

    def settings(self) -> dict[str, Any]:
        return {**self.fit.settings(), "structure": True}
