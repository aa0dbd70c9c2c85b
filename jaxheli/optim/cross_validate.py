"""Leave-one-window-out cross-validation of the output-error polish: which run length and how many rounds.

The polish's rounds (:mod:`jaxheli.optim.output_error`) end on runs over the whole record by default, which weighs
the slow, often unstable hover modes most; a model meant to predict a few seconds ahead may do better stopped on
shorter runs or after fewer rounds, and only data it was not fitted on can say so. The training flight is cut into
``W`` windows of equal length; for each window in turn the polish is run on the other ``W - 1`` (each its own
record with its own initial states, :class:`~jaxheli.problem.Records`) once per run length of :data:`FINALS`,
and the parameters after every round are scored on the window left out: the mean over its channels of the
normalised squared output error over runs of :data:`RUN_S` s, each from its least-squares initial state (the runs
of :func:`jaxheli.verify.verify`, without its per-channel bias; fit % is ``100 (1 - sqrt(nmse))``). The run length
and stopping round of lowest mean held-out error over the windows are chosen; the caller fits the whole flight with
them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import jax.numpy as jnp
import numpy as np

from .._progress import stage
from .._types import Array, ArrayLike, Float
from .._xla import quick_jit
from ..bounds import Free
from ..data.flight import FlightData
from ..data.preprocess import trim
from ..problem import Problem, Records, Settings, make_problem
from .output_error import in_runs, output_error
from .pem import Solver, pem_residuals
from .prior import Prior

FINALS: tuple[float | None, ...] = (5.0, 20.0, None)
"""Run lengths, s, of the polish's last rounds that the cross-validation chooses among (``None``: as long as the
data allow). Only lengths a fold can test are tried: each at most a window long (a fold's records are windows), so
a "whole record" of the folds is one window, and the whole-flight fit that follows caps its runs there too; a length
within :data:`RUN_S` of the window's is taken as the window's (no run of a few samples at a window's end)."""

RUN_S = 5.0
"""Length, s, of the runs a left-out window is scored over (:func:`jaxheli.verify.verify`'s default)."""


@dataclasses.dataclass(frozen=True)
class CrossValidation:
    """The choice and its evidence.

    Attributes:
        windows: ``W``, the number of windows (and folds).
        final: the chosen run length, s (at most a window long).
        rounds: the chosen number of rounds.
        heldout: per run length tried (``"5 s"``, ``"20 s"``, a window's length), the mean over folds of the held-out
            normalised squared error after each round (huge, never NaN, where a fold's model diverged); a fold that
            stopped early keeps its last round's score for the later rounds.
        folds: per run length, each fold's held-out error after each round ``[W][rounds]``.
    """

    windows: int
    final: float
    rounds: int
    heldout: dict[str, list[float]]
    folds: dict[str, list[list[float]]]

    def describe(self) -> str:
        """One line: the choice and its held-out error."""
        label = _label(self.final)
        return (f"runs of {label}, {self.rounds} round(s) chosen over {self.windows} windows (held-out error "
                f"{self.heldout[label][self.rounds - 1]:.4g}; " + ", ".join(
                    f"{k} {min(v):.4g}" for k, v in self.heldout.items()) + " at best)")

    def to_json(self) -> dict[str, Any]:
        """JSON-ready content."""
        return {"windows": self.windows, "final_s": self.final, "rounds": self.rounds, "run_s": RUN_S,
                "measure": "mean over the left-out window's channels of the normalised squared output error, "
                           f"runs of {RUN_S:g} s from the least-squares state", "heldout": self.heldout,
                "folds": self.folds}


def check_windows(flight: FlightData, count: int) -> int:
    """The samples in each of ``count`` windows of ``flight``; raises naming the flight where there are fewer than
    two windows or a window is shorter than two scoring runs."""
    size = flight.n_samples // max(count, 1)
    if count < 2 or size * flight.dt < 2 * RUN_S:
        raise ValueError(f"{flight.source}: {count} windows of {flight.duration:.3g} s leave "
                         f"{size * flight.dt:.3g} s each; cross-validation needs >= 2 windows of >= {2 * RUN_S:g} s")
    return size


def windows(flight: FlightData, count: int) -> list[FlightData]:
    """``flight`` cut into ``count`` contiguous windows of equal length (the last ``N mod count`` samples left out,
    so that every fold's records share one compiled solver); checked as :func:`check_windows` says."""
    size = check_windows(flight, count)
    return [trim(flight, drop_samples=(a, flight.n_samples - a - size)) for a in range(0, count * size, size)]


@quick_jit
def _heldout_error(problem: Problem, theta: Float[Array, "40"]) -> Float[Array, ""]:
    """Mean normalised squared output error of ``theta`` on ``problem`` (PEM's divergence-safe residuals: a model
    that diverges scores a huge error, never NaN)."""
    return jnp.mean(pem_residuals(problem, problem.sim(theta)) ** 2)


def _label(final: float) -> str:
    return f"{final:.4g} s"


def cross_validate(
    flight: FlightData,
    settings: Settings,
    start: Float[ArrayLike, "*starts 40"],
    count: int,
    *,
    rounds: int = 4,
    max_steps: int = 100,
    solver: Solver = "lm",
    free: Free = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    prior: Prior | None = None,
    finals: Sequence[float | None] = FINALS,
) -> CrossValidation:
    """Choose the output-error polish's final run length (of ``finals``, each capped at a window's length) and
    number of rounds (at most ``rounds``) by leave-one-window-out cross-validation over ``count`` windows of
    ``flight`` (see the module), every fold polished from ``start`` (one start ``[40]`` or several ``[S, 40]``, as
    :func:`~jaxheli.optim.output_error.output_error` takes them) under ``settings``; the other arguments as
    there."""
    cut = windows(flight, count)
    span = (cut[0].n_samples - 1) * flight.dt
    lengths = sorted({span if f is None or f > span - RUN_S else f for f in finals})
    parts = [make_problem(w, settings) for w in cut]
    scored = [in_runs(p.variant(x0="estimated"), RUN_S) for p in parts]
    folds: dict[str, list[list[float]]] = {_label(f): [] for f in lengths}
    for k in range(count):
        train = Records(tuple(p for j, p in enumerate(parts) if j != k))
        for final in lengths:
            with stage(f"cross-validation: window {k + 1} of {count} left out, runs of {_label(final)}") as now:
                res = output_error(train, start, rounds=rounds, solver=solver, max_steps=max_steps, free=free,
                                   rtol=rtol, atol=atol, prior=prior, final=final)
                errs = [float(_heldout_error(scored[k], jnp.asarray(r["theta"]))) for r in res.settings["rounds"]]
                errs += errs[-1:] * (rounds - len(errs))
                folds[_label(final)].append(errs)
                now.outcome = "held-out error by round " + ", ".join(f"{e:.4g}" for e in errs)
    heldout = {label: np.mean(np.asarray(rows), axis=0).tolist() for label, rows in folds.items()}
    best = min(((f, r) for f in lengths for r in range(rounds)), key=lambda fr: heldout[_label(fr[0])][fr[1]])
    return CrossValidation(count, best[0], best[1] + 1, heldout, folds)
