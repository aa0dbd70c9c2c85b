"""The population search: IWO or GA on the problem's search cost, ``K`` trials vmapped in one scan."""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Literal

import equinox as eqx
import jax
import numpy as np

from .._progress import stage
from ..optim.ga import GA
from ..optim.iwo import IWO
from ..optim.run import minimize, minimize_trials
from ._stage import Record, Stage, Starts, Task

_ENGINES = {"iwo": IWO, "ga": GA}


class Search(Stage):
    """IWO or GA on the search cost (the problem's ``cost``, scored in its ``precision``), from ``PRNGKey(seed)``.

    Attributes:
        engine: ``"iwo"`` (the paper's) or ``"ga"``.
        iterations: generations (the paper: 1000).
        options: further hyperparameters of :class:`~jaxheli.optim.IWO` / :class:`~jaxheli.optim.GA` (e.g.
            ``{"modulation": 3.0}``; default: the paper's settings).
        chunk, checkpoint, resume, progress: run control of :func:`jaxheli.optim.run.minimize` (generations per
            compiled call and between checkpoints; the checkpoint file; continue from it; a progress bar).
    """

    FIRST: ClassVar[bool | None] = True

    engine: Literal["iwo", "ga"] = "iwo"
    iterations: int = 1000
    options: dict[str, Any] = eqx.field(default_factory=dict)
    chunk: int = 50
    checkpoint: str | None = None
    resume: bool = False
    progress: bool = True

    def __check_init__(self) -> None:
        if self.engine not in _ENGINES:
            raise ValueError(f"Search: engine must be one of {tuple(_ENGINES)}, got {self.engine!r}")
        if self.iterations < 1 or self.chunk < 1:
            raise ValueError(f"Search: iterations and chunk must be >= 1, got {self.iterations}, {self.chunk}")
        known = {f.name for f in dataclasses.fields(_ENGINES[self.engine])} - {"lower", "upper", "iterations"}
        if set(self.options) - known:
            raise ValueError(f"Search: unknown options {sorted(set(self.options) - known)} of {self.engine.upper()}; "
                             f"it takes {sorted(known)}")

    @property
    def name(self) -> str:
        return self.engine

    def __call__(self, task: Task, starts: Starts | None) -> tuple[Starts, Record]:
        problem, trials = task.problem, task.trials
        bounds = problem.bounds
        engine = _ENGINES[self.engine](lower=bounds.lower, upper=bounds.upper, iterations=self.iterations,
                                       **self.options)
        keys = jax.random.split(jax.random.PRNGKey(task.seed), trials)
        control = {"chunk": self.chunk, "progress": self.progress, "checkpoint": self.checkpoint,
                   "resume": self.resume}
        with stage(f"{self.engine.upper()}: {trials} trial(s) of {self.iterations} generations on the "
                   f"{problem.settings.cost} cost (the first chunk compiles)") as now:
            cost_fn = problem.population_cost()
            run = (minimize_trials(engine, cost_fn, keys, **control) if trials > 1
                   else minimize(engine, cost_fn, keys[0], **control))
            found = Starts(np.asarray(run.best_theta).reshape(trials, -1), np.asarray(run.best_cost).reshape(trials))
            now.outcome = f"best cost {float(np.min(found.costs)):.6g}"
        return found, Record(history=np.asarray(run.history).reshape(trials, -1),
                             evaluations=int(np.sum(np.asarray(run.n_evaluations))))

    def settings(self) -> dict[str, Any]:
        return {"iterations": self.iterations, "engine_options": dict(self.options)}
