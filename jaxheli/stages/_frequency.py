"""The frequency-domain fit as a stage: each trial fits the record's frequency responses on Tischler's cost J
(CIFER), from its own start or the previous stage's trial."""

from __future__ import annotations

import inspect
import warnings
from typing import Any

import equinox as eqx
import numpy as np

from .._progress import stage
from .._types import Float
from ..optim.frequency_fit import FrequencyFitResult, IncoherentFlight, frequency_fit
from ..optim.output_error import output_error_problem
from ..problem import Problem, Records
from ._stage import Record, Stage, Starts, Task

_FIT_OPTIONS = frozenset(inspect.signature(frequency_fit).parameters) - {"data", "start", "seed", "settings"}
"""The keywords of :func:`~jaxheli.optim.frequency_fit.frequency_fit` a :class:`FrequencyFit` passes on."""


class FrequencyFit(Stage):
    """:func:`~jaxheli.optim.frequency_fit.frequency_fit` per trial; trial ``k`` draws its screened starts from
    ``seed + k``. At the head of a chain each trial also starts from ``start``; after another stage, from that
    stage's trial, which the trial keeps as its second start (:attr:`Starts.also`), and a record without a coherent
    pair skips the fit with a warning, the previous trials going on alone.

    Attributes:
        start: ``[40]`` a first start of every trial (head of a chain only; default: the screened draws only).
        options: keywords of the fit (``starts``, ``screen``, ``band``, ``min_coherence``, ``max_steps``, ...).
    """

    start: Float[np.ndarray, "40"] | None = None
    options: dict[str, Any] = eqx.field(default_factory=dict)

    def __check_init__(self) -> None:
        unknown = sorted(set(self.options) - _FIT_OPTIONS)
        if unknown:
            raise ValueError(f"FrequencyFit: unknown options {unknown}; the fit takes {sorted(_FIT_OPTIONS)}")

    @property
    def name(self) -> str:
        return "freq"

    def check_place(self, first: bool) -> None:
        if self.start is not None and not first:
            raise ValueError("FrequencyFit: start is for the head of a chain; after a stage it starts from its trials")

    def errors_problem(self, problem: Problem | Records, params: Float[np.ndarray, "40"]) -> Problem | Records:
        # restarts where unstable: a frequency fit may diverge over one run from rest
        return output_error_problem(problem, params)

    def __call__(self, task: Task, starts: Starts | None) -> tuple[Starts, Record]:
        first = [self.start] * task.trials if starts is None else list(starts.params)
        try:
            fits = [self._fit(task, first[k], k) for k in range(task.trials)]
        except IncoherentFlight as error:
            if starts is None:
                raise
            skipped = f"frequency fit skipped, IWO's best polished alone: {error}"
            warnings.warn(skipped, stacklevel=3)
            return Starts(starts.params, starts.costs), Record(skipped=skipped)
        found = Starts(np.stack([f.theta for f in fits]), np.array([f.j_average for f in fits]),
                       also=None if starts is None else starts.params)
        return found, Record(fits=fits)

    def _fit(self, task: Task, start: Float[np.ndarray, "40"] | None, k: int) -> FrequencyFitResult:
        """Trial ``k``'s fit, a stage of the progress lines."""
        with stage(f"frequency fit of trial {k + 1} of {task.trials} on Tischler's cost J") as now:
            fit = frequency_fit(task.problem, start=start, seed=task.seed + k, **self.options)
            now.outcome = (f"average J {fit.j_average:.1f} from {fit.settings['starts']} starts of up to "
                           f"{fit.settings['max_steps']} LM steps")
        return fit

    def settings(self) -> dict[str, Any]:
        return {"freq_options": dict(self.options)}
