"""Prediction-error minimisation (PEM): least squares on the segment-wise predictor's output errors.

The residual of ``theta`` is the simulated minus the measured output, each channel divided by the
standard deviation of its measured signal (so m/s, rad/s and rad weigh alike), flattened over time and
channels. The predictor is the multiple-shooting simulator (:func:`jaxheli.make_simulator` with
``segment``): it restarts from the measured states every ``segment`` seconds, so an open-loop unstable
hover model still gives bounded residuals. The solve is one ``optimistix.least_squares`` call
(Levenberg-Marquardt or Gauss-Newton) on the free parameters in the unit box coordinates of
:class:`jaxheli.bounds.Bounds` (each axis normalised to its bound width). Bounds: the residuals carry a penalty
``PENALTY (u - clip(u))`` (:meth:`~jaxheli.bounds.Bounds.penalty`) on the distance outside the box, the
solver's steps stay within :data:`~jaxheli.optim.boxed_lm.MARGIN` of it (:mod:`jaxheli.optim.boxed_lm`), and the
answer is clipped into the box: a path may cut briefly past a bound (holding parameters exactly at a bound stalled
fits whose truth lies near one) but cannot wander off. Unlike a sigmoid map ``lower + width sigmoid(z)``, this keeps
unit slope at and near a bound (a sigmoid flattens there and froze parameters that started within 0.1 % of a bound,
e.g. ``Nr`` at -10, in our tests).

Several records (:class:`jaxheli.problem.Records`) concatenate their residuals, so the sums of squares add; the
initial state of each can be fitted with the parameters (``fit``'s ``fit_x0``, as the output-error polish does).

Divergence: a residual beyond ``_BIG`` (normalised units) grows only logarithmically past it, and a
non-finite one reads as the float maximum, so a diverging candidate has a large finite cost and a finite,
useful Jacobian. The returned ``theta`` is the better of the start and the solver's answer.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._types import Array, ArrayLike, Float, Int
from .._xla import quick_jit
from ..bounds import Bounds, Free
from ..cost import paper_cost, pearson
from ..data.flight import FlightData
from ..model import N_PARAMS, PARAM_NAMES
from ..problem import Problem, Records, as_problem, parts
from .boxed_lm import FreeAxes, Solver, boxed_least_squares, least_squares_solver, step_bound
from .prior import Prior

_BIG = 1e3
"""Normalised residual (signal standard deviations) past which it is compressed logarithmically."""

def pem_residuals(problem: Problem, y: Float[Array, "*batch N k"]) -> Float[Array, "*batch Nk"]:
    """Normalised, divergence-safe errors ``(y - meas) / std(meas)``, flattened (time-major)."""
    err = (y - jnp.broadcast_to(problem.target, y.shape)) / jnp.broadcast_to(problem.scale, y.shape)
    return _compress(err).reshape(y.shape[:-2] + (-1,))


def pearson_residuals(problem: Problem, y: Float[Array, "*batch N k"]) -> Float[Array, "*batch k"]:
    """``1 - rho`` per channel: its sum of squares is the paper's cost (Eq. 7)."""
    return 1.0 - pearson(y, problem.target)


def residuals(problem: Problem | Records, theta: Float[Array, "40"]) -> Float[Array, " Nk"]:
    """PEM residuals of one parameter vector (every record's, concatenated)."""
    return jnp.concatenate([pem_residuals(part, part.sim(theta)) for part in parts(problem)], axis=-1)


def _compress(r: Array) -> Array:
    """Identity up to ``|r| = _BIG``, then ``_BIG (1 + log(|r| / _BIG))`` (C1); non-finite -> float max."""
    r = jnp.where(jnp.isfinite(r), r, jnp.finfo(r.dtype).max)
    mag = jnp.abs(r)
    tail = _BIG * (1.0 + jnp.log(jnp.maximum(mag, _BIG) / _BIG))
    return jnp.where(mag <= _BIG, r, jnp.sign(r) * tail)


PEM_DEFAULTS: dict[str, Any] = {"segment": 1.0, "x0": "measured"}
"""PEM's predictor when it is handed a flight: restarts from the measured states every second."""


def fitted_problem(
    data: FlightData | Problem | Records, defaults: dict[str, Any] | None = None, **settings: Any
) -> Problem | Records:
    """The problem a least-squares engine fits: :func:`~jaxheli.problem.as_problem` on the step-by-step scan
    simulator (under linearise/vmap/transpose it compiles faster than "blocked")."""
    return as_problem(data, defaults, **settings).variant(simulator="scan")


def start_vector(start: Float[ArrayLike, "40"] | None, bounds: Bounds) -> np.ndarray:
    """A solver's start: ``start[40]`` checked, or the middle of ``bounds``."""
    theta = bounds.midpoint() if start is None else np.asarray(start, dtype=np.float64)
    if theta.shape != (N_PARAMS,) or not np.all(np.isfinite(theta)):
        raise ValueError(f"start must be 40 finite parameters, got shape {theta.shape}")
    return theta


Objective = Literal["pem", "pearson"]


class _Boxed(eqx.Module):
    """An objective on ``problem`` and the parameters its solver moves (``axes``: the start is ``axes.base``)."""

    problem: Problem | Records
    axes: FreeAxes
    objective: Objective = eqx.field(static=True)
    prior: Prior | None = None

    def of_outputs(self, part: Problem, y: Float[Array, "*batch N k"]) -> Float[Array, "*batch m"]:
        """The objective's residuals of one record's outputs."""
        return (pem_residuals if self.objective == "pem" else pearson_residuals)(part, y)

    def of_prior(self, theta: Float[Array, "40"]) -> Float[Array, " n"]:
        """The prior's residuals over the free axes (none without a prior, :mod:`jaxheli.optim.prior`)."""
        if self.prior is None:
            return jnp.zeros((0,), theta.dtype)
        return self.prior.residuals(theta, np.flatnonzero(np.array(self.axes.free)))


def _residual(v: Array, boxed: _Boxed) -> Array:
    theta = boxed.axes.theta(v)
    return jnp.concatenate([boxed.of_outputs(part, part.sim(theta)) for part in parts(boxed.problem)]
                           + [boxed.of_prior(theta)])


def _scores(theta: Array, boxed: _Boxed) -> tuple[Array, Array, Array]:
    """The objective's sum of squares (the prior's included), the paper's cost and the PEM sum of squares (the
    output errors' alone), added over records."""
    loss = jnp.sum(boxed.of_prior(theta) ** 2)
    cost = rss = jnp.zeros((), theta.dtype)
    for part in parts(boxed.problem):
        y = part.sim(theta)
        loss = loss + jnp.sum(boxed.of_outputs(part, y) ** 2)
        cost = cost + paper_cost(y, part.target)
        rss = rss + jnp.sum(pem_residuals(part, y) ** 2)
    return loss, cost, rss


def _score(v0: Array, v: Array, boxed: _Boxed) -> tuple[Array, tuple[Array, Array, Array]]:
    """The objective's sum of squares at the start (``base``) and at the answer ``v`` clipped into the box, and their
    parameters, paper's costs and PEM sums of squares (``[2]`` each), from one vmapped run: one copy of the simulator
    in the compiled program."""
    del v0
    pair = jnp.stack([boxed.axes.base, boxed.axes.theta(Bounds.clip_unit(v))])
    loss, cost, rss = jax.vmap(_scores, in_axes=(0, None))(pair, boxed)
    return loss, (pair, cost, rss)


@quick_jit
def _solve(
    boxed: _Boxed, solver: optx.AbstractLeastSquaresSolver, limit: Int[Array, ""], bound: int
) -> tuple[Array, Array, Array, Array, Array, Array, optx.RESULTS]:
    """One least-squares solve of ``boxed``'s residuals of at most ``limit`` steps (``bound`` the compiled limit,
    :func:`~jaxheli.optim.boxed_lm.step_bound`: one program for every step count); keeps the start (``base``) unless
    the solver beat it.

    Returns ``theta, cost_start, cost, rss_start, rss, n_steps, result``.
    """
    sol = boxed_least_squares(_residual, solver, boxed.axes.start(), boxed, bound, _score, limit)
    pair, cost, rss = sol.aux
    return sol.kept(*pair), cost[0], sol.kept(*cost), rss[0], sol.kept(*rss), sol.num_steps, sol.result


_RESULT_NAMES = (
    "successful", "max_steps_reached", "nonlinear_max_steps_reached", "nonlinear_divergence", "nonfinite",
    "nonfinite_input", "singular", "breakdown", "stagnation", "conlim",
)


def _result_name(result: optx.RESULTS) -> str:
    """The name of an optimistix result (``"successful"``, ``"max_steps_reached"``, ...)."""
    names = [n for n in _RESULT_NAMES if hasattr(optx.RESULTS, n) and bool(result == getattr(optx.RESULTS, n))]
    return names[0] if names else "unknown"


@dataclasses.dataclass(frozen=True)
class PEMResult:
    """Outcome of :func:`pem` (or of a polish).

    Attributes:
        theta: ``[40]`` identified parameters (physical units; the start where the solver did not improve).
        theta_start: ``[40]`` the start.
        free: names of the fitted parameters.
        cost_start, cost: the paper's Pearson cost (Eq. 7) of the same simulation, before and after.
        rss_start, rss: sum of squared normalised residuals (the least-squares objective), before and after.
        n_steps: solver steps taken.
        result: optimistix result name (``"successful"``, ``"max_steps_reached"``, ...); ``message`` its text.
        success: the solver converged (its termination test passed within ``max_steps``).
        settings: simulator and solver settings.
    """

    theta: np.ndarray
    theta_start: np.ndarray
    free: tuple[str, ...]
    cost_start: float
    cost: float
    rss_start: float
    rss: float
    n_steps: int
    result: str
    message: str
    success: bool
    settings: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values; parameter vectors as ``{name: value}``."""
        out = dataclasses.asdict(self)
        out["theta"] = dict(zip(PARAM_NAMES, self.theta.tolist()))
        out["theta_start"] = dict(zip(PARAM_NAMES, self.theta_start.tolist()))
        out["free"] = list(self.free)
        return out


def _result(raw, base: np.ndarray, mask: np.ndarray, settings: dict[str, Any]) -> PEMResult:
    *values, result = raw
    theta, c0, c1, r0, r1, steps = (np.asarray(v) for v in values)
    name = _result_name(result)
    return PEMResult(
        theta=theta,
        theta_start=base,
        free=tuple(n for n, m in zip(PARAM_NAMES, mask) if m),
        cost_start=float(c0),
        cost=float(c1),
        rss_start=float(r0),
        rss=float(r1),
        n_steps=int(steps),
        result=name,
        message=optx.RESULTS[result],
        success=name == "successful",
        settings=settings,
    )


def pem(
    data: FlightData | Problem,
    *,
    start: Float[ArrayLike, "40"] | None = None,
    solver: Solver = "lm",
    max_steps: int = 200,
    free: Free = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    prior: Prior | None = None,
    **settings: Any,
) -> PEMResult:
    """Fit the hover model to a record by prediction-error minimisation (one jitted optimistix solve).

    Args:
        data: a :class:`~jaxheli.problem.Problem`, or a flight (its problem under PEM's defaults,
            :data:`PEM_DEFAULTS`: the predictor restarts from the measured states every 1 s); its sticks
            drive the predictor, its outputs are the targets.
        start: initial ``theta[40]`` (default: the middle of the bounds, pinned parameters at their value);
            returned unchanged where the solver does not lower the objective.
        solver: ``"lm"`` (Levenberg-Marquardt, default) or ``"gn"`` (Gauss-Newton).
        max_steps: solver step limit; reaching it is reported (``success=False``), not raised. A run-time
            value under a compiled bound (:func:`~jaxheli.optim.boxed_lm.step_bound`): step counts up to the same
            power of two share one compiled solver.
        free: free parameters (mask or names; default every axis the bounds leave free); the rest stay at
            ``start``.
        rtol, atol: optimistix's Cauchy termination tolerances on the unit coordinates and the loss.
        prior: a Gaussian prior whose residuals join the output errors' (:class:`~jaxheli.optim.prior.Prior`;
            ``rss`` stays the output errors' sum of squares).
        settings: :class:`~jaxheli.problem.Settings` fields: ``outputs`` (default: the measured channels
            without a, b), ``segment`` (s; ``None``: one open-loop run, the paper's simulation), ``hold``,
            ``x0`` (``"measured"`` starts the predictor from the first measured states), ``g``, and the box
            ``lower``/``upper`` the answer stays in.
    """
    problem = fitted_problem(data, PEM_DEFAULTS, **settings)
    return fit(problem, start, "pem", solver, max_steps, free, rtol, atol, prior)


def fit(
    problem: Problem | Records,
    start: Float[ArrayLike, "40"] | None,
    objective: Objective,
    solver: Solver,
    max_steps: int,
    free: Free,
    rtol: float,
    atol: float,
    prior: Prior | None = None,
    bound: int | None = None,
) -> PEMResult:
    """Least squares on ``objective``'s residuals over the free parameters, in ``problem``'s box (shared by
    :func:`pem` and :func:`~jaxheli.optim.polish.polish`); over several records the residuals are concatenated,
    so the sums of squares (and the paper's costs reported) add. A ``prior`` (:class:`~jaxheli.optim.prior.Prior`)
    appends its residuals of the free parameters: the one place every local fit takes it; the start is kept unless
    the answer lowers the objective with them. ``bound``: the step count whose compiled bound the solve takes
    (default ``max_steps``; :func:`~jaxheli.optim.boxed_lm.step_bound`), so that the legs of one budget (a race's
    steps and the leader's rest) share one program."""
    base, mask = start_vector(start, problem.bounds), problem.bounds.free_mask(free)
    boxed = _Boxed(problem.one_program(), FreeAxes(problem.bounds, base, mask), objective, prior)
    raw = _solve(boxed, least_squares_solver(solver, rtol, atol, int(mask.sum())), jnp.asarray(int(max_steps)),
                 step_bound(max(max_steps, bound or 0)))
    settings = {"objective": objective, "solver": solver, "max_steps": int(max_steps), "rtol": rtol, "atol": atol,
                "simulator": [part.sim.describe() for part in parts(problem)] if isinstance(problem, Records)
                else problem.sim.describe(), "prior": prior is not None}
    return _result(raw, base, mask, settings)
