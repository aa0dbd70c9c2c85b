"""A stage of an identification: an immutable module of its options that maps the trials found so far to new ones
(:class:`Starts`) and reports what only it knows (:class:`Record`); :func:`jaxheli.identify` runs a chain of them."""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Sequence
from typing import Any, ClassVar

import equinox as eqx
import numpy as np

from .._types import Float
from ..data.flight import FlightData
from ..optim.frequency_fit import FrequencyFitResult
from ..optim.structure import StructureResult
from ..problem import Problem, Records


@dataclasses.dataclass(frozen=True)
class Task:
    """What every stage of one identification shares.

    Attributes:
        problem: the training problem, simulated from rest (the search's; a stage may fit a variant of it).
        data: the training record as the caller gave it (cross-validation cuts one flight into windows).
        trials: ``K``, the independent trials.
        seed: the run's PRNG seed; each stage draws from it as its engine does.
    """

    problem: Problem | Records
    data: FlightData | Sequence[FlightData] | Problem | Records
    trials: int
    seed: int


@dataclasses.dataclass(frozen=True)
class Starts:
    """The trials one stage hands to the next.

    Attributes:
        params: ``[K, 40]`` each trial's parameters.
        costs: ``[K]`` each trial's cost on the stage's own objective.
        also: ``[K, 40]`` a second start of each trial for the polish (the search's best beside the frequency
            fit's), or ``None``.
    """

    params: Float[np.ndarray, "K 40"]
    costs: Float[np.ndarray, " K"]
    also: Float[np.ndarray, "K 40"] | None = None

    @property
    def best(self) -> int:
        """Index of the trial of lowest cost."""
        return int(np.argmin(self.costs))


@dataclasses.dataclass(frozen=True)
class Record:
    """What the stages of a chain report beside their trials; each field is set by the stage that knows it.

    Attributes:
        history: ``[K, iterations]`` best cost per generation of the population search.
        evaluations: candidates the population search scored.
        fits: each trial's frequency fit.
        skipped: why the frequency fit was skipped (no coherent pair), its warning.
        polish: the polish's summary (``IdentificationResult.polish``).
        structure: the model-structure determination.
        convergence: each trial's local fit: Levenberg-Marquardt ``steps``, the solver's ``result`` and whether it
            ``converged`` (its termination test passed within the step limit).
    """

    history: Float[np.ndarray, "K iterations"] | None = None
    evaluations: int | None = None
    fits: list[FrequencyFitResult] | None = None
    skipped: str | None = None
    polish: dict[str, Any] | None = None
    structure: StructureResult | None = None
    convergence: list[dict[str, Any]] | None = None

    def merge(self, later: Record) -> Record:
        """This record with the fields ``later`` sets."""
        return dataclasses.replace(self, **{k: v for k, v in vars(later).items() if v is not None})


class Stage(eqx.Module):
    """One step of an identification chain (see the module)."""

    FIRST: ClassVar[bool | None] = None
    """``True``: the stage begins a chain; ``False``: it needs a stage before it; ``None``: either."""

    @property
    @abc.abstractmethod
    def name(self) -> str:
        """The stage's name in a method's name (``"iwo"``, ``"freq"``, ``"polish"``, ...)."""

    @abc.abstractmethod
    def __call__(self, task: Task, starts: Starts | None) -> tuple[Starts, Record]:
        """New trials from ``starts`` (``None`` for the first stage: ``task.trials`` of its own), and the record."""

    def check_place(self, first: bool) -> None:
        """Refuse a place in a chain (``first``: at its head) the stage cannot take."""
        if self.FIRST is not None and first != self.FIRST:
            raise ValueError(f"stage {self.name!r} " + ("begins a chain" if self.FIRST else "needs a stage before it"))

    def check(self, task: Task) -> None:
        """Refuse, before any stage runs, what this stage cannot do on ``task`` (default: nothing)."""

    def fitted(self, problem: Problem | Records) -> Problem | Records:
        """The variant of the task's problem this stage fits; the training scores of a chain ending here use it."""
        return problem

    def errors_problem(self, problem: Problem | Records, params: Float[np.ndarray, "40"]) -> Problem | Records:
        """The problem the standard errors at ``params`` are computed on when the chain ends here."""
        return self.fitted(problem)

    @abc.abstractmethod
    def settings(self) -> dict[str, Any]:
        """The stage's options under the names of ``IdentificationResult.settings``."""


def check_chain(stages: Sequence[Stage]) -> tuple[Stage, ...]:
    """``stages`` as a chain, each checked at its place (:meth:`Stage.check_place`)."""
    if not stages or not all(isinstance(s, Stage) for s in stages):
        raise ValueError(f"identify: a chain is one or more stages, got {stages!r}")
    for i, stage in enumerate(stages):
        stage.check_place(i == 0)
    return tuple(stages)
