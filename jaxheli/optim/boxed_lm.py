"""Levenberg-Marquardt and Gauss-Newton whose iterates stay in a box: an active-set solve of each step.

The least-squares engines solve in unit box coordinates (:class:`jaxheli.bounds.Bounds`): the first
``n_bounded`` entries of ``y`` are kept in ``[-margin, 1 + margin]``; any others (fitted initial states) are
free. Both solvers are optimistix's Gauss-Newton family (:class:`optimistix.AbstractGaussNewton`: its
trust-region acceptance and Cauchy termination) with one descent, :class:`BoxedDampedNewton`:

1. at each accepted point it materialises the Jacobian ``J`` (forward mode: one batched tangent per unknown, no
   transpose; for a long record a chunk of unknowns at a time, :mod:`jaxheli.optim.jacobian`), ``J^T J``, the
   gradient ``g = J^T r`` and the axes held by the gradient: bounded axes at a bound whose gradient points out of
   the box, and unknowns no residual depends on (a zero column). They take no step;
2. each trial step minimises the damped Gauss-Newton model ``|r + J d|^2 + lambda |d|^2`` on the other axes
   (``lambda = 1 / step_size``, as :class:`optimistix.LevenbergMarquardt`; Gauss-Newton: ``lambda = 0`` and a
   pseudo-inverse), then moves the axes that ``d`` carries out of the box to their bound, holds them there and
   minimises again over the rest (:data:`_PASSES` times: an active-set solve of the box-constrained model, so a
   step along a poorly resolved direction is cut by the model rather than by clipping it afterwards); what
   still crosses a bound is clipped.

Without a box its iterates are those of optimistix's own Levenberg-Marquardt (``lineax.Normal(SVD)`` on the
linearised residuals, which transposes them), in less time: forward mode needs no transpose.

Every engine drives it the same way (:func:`boxed_least_squares`): residuals of the unit coordinates with the
penalty past the box appended (:meth:`jaxheli.bounds.Bounds.penalty`), steps kept within :data:`MARGIN` of it; then,
where that answer lies outside the box, a second pass from it clipped into the box with steps kept in the box itself
(the axes that want out held at their bound, the rest solved again), so the answer is feasible and scores no worse
than the clipped one; it is kept only where it is finite and scores no worse than the start.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal, TypeVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._types import Array, Bool, Float, Int
from ..bounds import Bounds
from .jacobian import jacobian_transpose

Solver = Literal["lm", "gn"]

_RCOND = 1e-12
"""Gauss-Newton: eigenvalues of ``J^T J`` below this fraction of the largest are treated as zero."""
_PASSES = 4
"""Times a trial step is solved again with the axes it would carry out of the box held at the bound."""


class _DescentState(eqx.Module):
    y: Float[Array, " n"]
    free: Bool[Array, " n"]
    """Axes not held at a bound by the gradient."""
    hessian: Float[Array, "n n"]
    """``J^T J`` (Gauss-Newton)."""
    grad: Float[Array, " n"]


class BoxedDampedNewton(optx.AbstractDescent):
    """The damped-Newton (``damped=True``) or Gauss-Newton step, kept within ``margin`` of the unit box on the
    first ``n_bounded`` axes (see the module)."""

    n_bounded: int = eqx.field(static=True)
    damped: bool = eqx.field(static=True, default=True)
    margin: Float[Array, ""] = eqx.field(default=0.0, converter=jnp.asarray)
    """A run-time value, so that the driver's passes with and without a margin share one compiled solve."""

    def init(self, y: Float[Array, " n"], f_info_struct: optx.FunctionInfo.ResidualJac) -> _DescentState:
        del f_info_struct
        n = y.shape[0]
        return _DescentState(y, jnp.ones((n,), bool), jnp.zeros((n, n), y.dtype), jnp.zeros((n,), y.dtype))

    def query(
        self, y: Float[Array, " n"], f_info: optx.FunctionInfo.ResidualJac, state: _DescentState
    ) -> _DescentState:
        del state
        jac_t = jacobian_transpose(f_info.jac.mv, y.shape[0], f_info.residual.shape[0], y.dtype)
        grad = jac_t @ f_info.residual
        bounded = jnp.arange(y.shape[0]) < self.n_bounded
        lo, hi = -self.margin, 1.0 + self.margin
        free = ~(bounded & (((y <= lo) & (grad > 0.0)) | ((y >= hi) & (grad < 0.0)))) & jnp.any(jac_t != 0.0, axis=1)
        return _DescentState(y, free, jac_t @ jac_t.T, grad)

    def _solve(
        self, state: _DescentState, lam: Float[Array, ""], free: Bool[Array, " n"], fixed: Float[Array, " n"]
    ) -> Float[Array, " n"]:
        """The minimiser of the damped (``lam``) Gauss-Newton model over the ``free`` axes, the others taking
        their ``fixed`` step."""
        both = free[:, None] & free[None, :]
        eigvals, eigvecs = jnp.linalg.eigh(jnp.where(both, state.hessian, 0.0))
        eigvals = jnp.maximum(eigvals, 0.0)
        if self.damped:
            inverse = 1.0 / (eigvals + lam)
        else:
            resolved = eigvals > _RCOND * jnp.max(eigvals)
            inverse = jnp.where(resolved, 1.0 / jnp.where(resolved, eigvals, 1.0), 0.0)
        rhs = jnp.where(free, state.grad + state.hessian @ fixed, 0.0)
        return jnp.where(free, -(eigvecs @ (inverse * (eigvecs.T @ rhs))), fixed)

    def step(self, step_size: Float[Array, ""], state: _DescentState) -> tuple[Float[Array, " n"], optx.RESULTS]:
        tiny = step_size <= jnp.finfo(step_size.dtype).eps
        lam = jnp.where(tiny, jnp.finfo(step_size.dtype).max, 1.0 / jnp.where(tiny, 1.0, step_size))
        y, bounded = state.y, jnp.arange(state.y.shape[0]) < self.n_bounded
        lo, hi = -self.margin, 1.0 + self.margin
        held, fixed = ~state.free, jnp.zeros_like(y)
        for _ in range(_PASSES):
            diff = self._solve(state, lam, ~held, fixed)
            below, above = bounded & ~held & (y + diff < lo), bounded & ~held & (y + diff > hi)
            fixed = jnp.where(below, lo - y, jnp.where(above, hi - y, fixed))
            held = held | below | above
        diff = self._solve(state, lam, ~held, fixed)
        return jnp.where(bounded, jnp.clip(y + diff, lo, hi) - y, diff), optx.RESULTS.successful


def _quiet(**_: object) -> None:
    """No progress printing (optimistix's ``verbose`` hook)."""


class BoxedLeastSquares(optx.AbstractGaussNewton):
    """Levenberg-Marquardt (a classical trust region on ``lambda``) or Gauss-Newton (full steps) whose first
    ``n_bounded`` unknowns stay within ``margin`` of the unit box (see the module)."""

    rtol: float
    atol: float
    norm: Callable
    descent: BoxedDampedNewton
    search: optx.AbstractSearch
    verbose: Callable

    def __init__(self, rtol: float, atol: float, n_bounded: int, solver: Solver = "lm", margin: float = 0.0):
        if solver not in ("lm", "gn"):
            raise ValueError(f"solver must be 'lm' or 'gn', got {solver!r}")
        self.rtol, self.atol = rtol, atol
        self.norm = optx.max_norm
        self.descent = BoxedDampedNewton(int(n_bounded), damped=solver == "lm", margin=float(margin))
        self.search = optx.ClassicalTrustRegion() if solver == "lm" else optx.LearningRate(1.0)
        self.verbose = _quiet

    def terminate(self, fn, y, args, options, state, tags):
        """Optimistix's termination, and a stop after ``options[STEP_LIMIT]`` steps where given (a run-time limit
        under the compiled ``max_steps``, reported as reaching it: the same iterates, one program for every limit)."""
        done, result = super().terminate(fn, y, args, options, state, tags)
        if STEP_LIMIT not in options:
            return done, result
        hit = ~done & (state.num_steps >= options[STEP_LIMIT])
        return done | hit, optx.RESULTS.where(hit, optx.RESULTS.nonlinear_max_steps_reached, result)


STEP_LIMIT = "step_limit"
"""Key of the solver's ``options`` holding a run-time step limit (:meth:`BoxedLeastSquares.terminate`)."""


def step_bound(max_steps: int) -> int:
    """The compiled step bound of a solve of ``max_steps`` steps: the next power of two, at least 64, so that solves
    of different step counts (a diagnosis candidate's 15 and its reference's 60; a polish race's 20 and the rest of
    its round) share one program, the count itself a run-time ``limit`` (:func:`boxed_least_squares`)."""
    return max(64, 1 << (int(max_steps) - 1).bit_length())


MARGIN = 0.2
"""How far outside the unit box (in bound widths) an iterate may go; :meth:`~jaxheli.bounds.Bounds.penalty` pulls
it back. Wide enough to follow the unbounded penalty path (a much smaller margin stalls with parameters pinned at
bounds the truth does not touch), narrow enough that a poor start does not wander far outside."""


def least_squares_solver(solver: Solver, rtol: float, atol: float, n_bounded: int) -> BoxedLeastSquares:
    """The least-squares solver whose first ``n_bounded`` unknowns stay in ``[-MARGIN, 1 + MARGIN]``
    (:class:`BoxedLeastSquares`): Levenberg-Marquardt (``"lm"``) or Gauss-Newton (``"gn"``). ``n_bounded`` is small,
    so ``J^T J`` (35 x 35) is cheap and its eigen decomposition copes with the exactly unresolved directions (e.g.
    ``Nrfb``/``Kr``, which enter only as a product)."""
    return BoxedLeastSquares(rtol, atol, n_bounded, solver, MARGIN)


class FreeAxes(eqx.Module):
    """The parameters of a solver's unknowns: the ``free`` axes of ``bounds`` at unit coordinates, the others at
    ``base`` (physical units)."""

    bounds: Bounds
    base: Float[Array, " dim"] = eqx.field(converter=jnp.asarray)
    free: tuple[bool, ...] = eqx.field(static=True, converter=lambda mask: tuple(bool(m) for m in mask))

    def theta(self, v: Float[Array, " n"]) -> Float[Array, " dim"]:
        """Physical parameters: the free axes from ``v`` (unclipped), the others from ``base``."""
        return self.bounds.embed(self.base, np.array(self.free), v)

    def start(self) -> Float[Array, " n"]:
        """``base`` on the free axes, in unit coordinates clipped into the box."""
        return Bounds.clip_unit(self.bounds.to_unit(self.base)[np.flatnonzero(np.array(self.free))])


Args = TypeVar("Args")
Aux = TypeVar("Aux")


class BoxedSolution(eqx.Module):
    """Outcome of :func:`boxed_least_squares`.

    Attributes:
        value: ``[n]`` the unit coordinates kept: the driver's answer (in the box), or the start.
        improved: whether the answer replaced the start.
        loss: ``[2]`` the score of the start and of the answer.
        aux: what the scoring computed besides (e.g. other measures of both points).
        num_steps: solver steps taken (both passes).
        result: optimistix's result (the first pass's).
    """

    value: Float[Array, " n"]
    improved: Bool[Array, ""]
    loss: Float[Array, "2"]
    aux: Any
    num_steps: Int[Array, ""]
    result: optx.RESULTS

    @property
    def successful(self) -> Bool[Array, ""]:
        """The solver converged (its termination test passed within ``max_steps``)."""
        return self.result == optx.RESULTS.successful

    def kept(self, start: Any, answer: Any) -> Any:
        """Of a value at the start and the same at the answer (pytrees of one structure), the one kept."""
        return jax.tree.map(lambda a, b: jnp.where(self.improved, b, a), start, answer)


SETTLE_STEPS = 16
"""Most steps of the driver's second pass (:func:`boxed_least_squares`), which starts from the first pass's answer
clipped into the box: where that answer had converged, a few steps re-solve the axes the clipping moved."""


def _clip_bounded(u: Float[Array, " n"], n_bounded: int) -> Float[Array, " n"]:
    """``u`` with its first ``n_bounded`` entries clipped into the unit box."""
    return jnp.where(jnp.arange(u.shape[0]) < n_bounded, Bounds.clip_unit(u), u)


def boxed_least_squares(
    fit: Callable[[Float[Array, " n"], Args], Float[Array, " m"]],
    solver: BoxedLeastSquares,
    u0: Float[Array, " n"],
    args: Args,
    max_steps: int,
    score: Callable[[Float[Array, " n"], Float[Array, " n"], Args], tuple[Float[Array, "2"], Aux]] | None = None,
    limit: Int[Array, ""] | None = None,
    settle: int = SETTLE_STEPS,
) -> BoxedSolution:
    """Least squares on ``fit(u, args)``'s residuals of the unit coordinates ``u``, the penalty past the box
    appended, from ``u0``, in two passes of one compiled solve (reaching a step limit is reported, not raised):

    1. ``solver`` with its margin (steps within :data:`MARGIN` of the box), at most ``limit`` steps (an array, at
       most ``max_steps``: one program for every limit; default ``max_steps``);
    2. where that answer lies outside the box: from it clipped into the box, steps kept in the box (margin 0), at
       most ``settle`` steps (default :data:`SETTLE_STEPS`) and the steps the first pass left of ``limit`` (the
       limit holds for both). Of the clipped answer and this one, the lower penalised sum of squares is the
       answer: it lies in the box and scores no worse than the clipped first answer. ``settle=0`` keeps the
       clipped answer: for residuals that are a function of the clipped point already (a diagnosis's effect
       fits), it has the solver's own residuals and no penalty.

    The start is kept unless the answer is finite and scores no worse. ``score(u0, answer, args)`` gives the objective
    at both ``[2]`` and whatever else it computed with them (:attr:`BoxedSolution.aux`); by default the penalised
    residuals' sum of squares. ``num_steps`` counts both passes' steps; ``result`` is the first pass's.
    """
    n_bounded = solver.descent.n_bounded

    def penalised(u: Float[Array, " n"], args: Args) -> Float[Array, " r"]:
        return jnp.concatenate([fit(u, args), Bounds.penalty(u)])

    def solve(
        carry: tuple[Float[Array, " n"], Int[Array, ""]], margin: Float[Array, ""]
    ) -> tuple[tuple[Float[Array, " n"], Int[Array, ""]], tuple[Float[Array, " n"], Int[Array, ""], optx.RESULTS]]:
        u, steps = carry
        sol = optx.least_squares(penalised, eqx.tree_at(lambda s: s.descent.margin, solver, margin), u, args=args,
                                 options={STEP_LIMIT: steps}, max_steps=max_steps, throw=False)
        clipped, taken = _clip_bounded(sol.value, n_bounded), sol.stats["num_steps"]
        budget = jnp.where(jnp.any(clipped != sol.value), jnp.clip(steps - taken, 0, settle), 0)
        return (clipped, budget), (clipped, taken, sol.result)

    first = jnp.asarray(max_steps if limit is None else limit)
    margins = jnp.stack([solver.descent.margin, jnp.zeros_like(solver.descent.margin)])
    _, (ends, steps, results) = jax.lax.scan(solve, (u0, first), margins)
    answer = ends[1]
    if not solver.descent.damped:  # Levenberg-Marquardt accepts only steps that lower the sum; Gauss-Newton any
        sums = jax.vmap(lambda u: jnp.sum(penalised(u, args) ** 2))(ends)
        answer = jnp.where(sums[1] <= sums[0], ends[1], ends[0])
    if score is None:
        loss, aux = jax.vmap(lambda u: jnp.sum(penalised(u, args) ** 2))(jnp.stack([u0, answer])), None
    else:
        loss, aux = score(u0, answer, args)
    improved = jnp.all(jnp.isfinite(answer)) & (loss[1] <= loss[0])
    value = jnp.where(improved, answer, u0)
    return BoxedSolution(value, improved, loss, aux, jnp.sum(steps), jax.tree.map(lambda r: r[0], results))
