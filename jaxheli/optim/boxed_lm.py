"""Levenberg-Marquardt and Gauss-Newton that stay inside the unit box: projected, with an active set.

The least-squares engines solve in unit box coordinates (:class:`jaxheli.bounds.Bounds`): the first
``n_bounded`` entries of ``y`` lie in ``[0, 1]``; any others (fitted initial states) are free. Both solvers are
optimistix's Gauss-Newton family (:class:`optimistix.AbstractGaussNewton`: its trust-region acceptance and
Cauchy termination) with one descent, :class:`BoxedDampedNewton`:

1. at each accepted point it materialises the Jacobian ``J`` (forward mode: one batched tangent per unknown, no
   transpose), the gradient ``g = J^T r`` and the *active set*: bounded axes at a bound whose gradient points
   out of the box (``y = 0, g > 0`` or ``y = 1, g < 0``). Their columns of ``J`` are zeroed, so they take no step;
2. each trial step solves ``(J^T J + lambda I) d = -g`` on the other axes (``lambda = 1 / step_size``, as
   :class:`optimistix.LevenbergMarquardt`; Gauss-Newton: a pseudo-inverse of ``J^T J``) from one eigen
   decomposition of ``J^T J`` per accepted point, and is projected into the box (``clip(y + d) - y``).

So the model is only ever evaluated inside the box (a penalty on the distance outside, as before, let
100-200 steps from a poor start wander out of the box and return the start), an axis can leave a bound again
when its gradient turns, and the trust region sees the projected step's own predicted reduction.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import equinox as eqx
import jax.numpy as jnp
import optimistix as optx

from .._types import Array, Bool, Float

Solver = Literal["lm", "gn"]

_RCOND = 1e-12
"""Gauss-Newton: eigenvalues of ``J^T J`` below this fraction of the largest are treated as zero."""


class _DescentState(eqx.Module):
    y: Float[Array, " n"]
    free: Bool[Array, " n"]
    eigvals: Float[Array, " n"]
    eigvecs: Float[Array, "n n"]
    grad: Float[Array, " n"]
    """``eigvecs^T g`` on the free axes: the gradient in the eigenbasis of ``J^T J``."""


class BoxedDampedNewton(optx.AbstractDescent):
    """The projected damped-Newton (``damped=True``) or Gauss-Newton step in the unit box (see the module)."""

    n_bounded: int = eqx.field(static=True)
    damped: bool = eqx.field(static=True, default=True)

    def init(self, y: Float[Array, " n"], f_info_struct: optx.FunctionInfo.ResidualJac) -> _DescentState:
        del f_info_struct
        n = y.shape[0]
        zeros = jnp.zeros((n,), y.dtype)
        return _DescentState(y, jnp.ones((n,), bool), zeros, jnp.zeros((n, n), y.dtype), zeros)

    def query(
        self, y: Float[Array, " n"], f_info: optx.FunctionInfo.ResidualJac, state: _DescentState
    ) -> _DescentState:
        del state
        jac = f_info.jac.as_matrix()
        grad = jac.T @ f_info.residual
        bounded = jnp.arange(y.shape[0]) < self.n_bounded
        active = bounded & (((y <= 0.0) & (grad > 0.0)) | ((y >= 1.0) & (grad < 0.0)))
        free = ~active
        jac = jnp.where(free, jac, 0.0)
        eigvals, eigvecs = jnp.linalg.eigh(jac.T @ jac)
        return _DescentState(y, free, jnp.maximum(eigvals, 0.0), eigvecs, eigvecs.T @ jnp.where(free, grad, 0.0))

    def step(self, step_size: Float[Array, ""], state: _DescentState) -> tuple[Float[Array, " n"], optx.RESULTS]:
        if self.damped:
            tiny = step_size <= jnp.finfo(step_size.dtype).eps
            lam = jnp.where(tiny, jnp.finfo(step_size.dtype).max, 1.0 / jnp.where(tiny, 1.0, step_size))
            inverse = 1.0 / (state.eigvals + lam)
        else:
            resolved = state.eigvals > _RCOND * jnp.max(state.eigvals)
            inverse = jnp.where(resolved, 1.0 / jnp.where(resolved, state.eigvals, 1.0), 0.0)
        diff = jnp.where(state.free, -(state.eigvecs @ (inverse * state.grad)), 0.0)
        bounded = jnp.arange(diff.shape[0]) < self.n_bounded
        projected = jnp.where(bounded, jnp.clip(state.y + diff, 0.0, 1.0) - state.y, diff)
        return projected, optx.RESULTS.successful


def _quiet(**_: object) -> None:
    """No progress printing (optimistix's ``verbose`` hook)."""


class BoxedLeastSquares(optx.AbstractGaussNewton):
    """Levenberg-Marquardt (a classical trust region on ``lambda``) or Gauss-Newton (full steps) whose iterates
    stay in the unit box (see the module)."""

    rtol: float
    atol: float
    norm: Callable
    descent: BoxedDampedNewton
    search: optx.AbstractSearch
    verbose: Callable

    def __init__(self, rtol: float, atol: float, n_bounded: int, solver: Solver = "lm"):
        if solver not in ("lm", "gn"):
            raise ValueError(f"solver must be 'lm' or 'gn', got {solver!r}")
        self.rtol, self.atol = rtol, atol
        self.norm = optx.max_norm
        self.descent = BoxedDampedNewton(int(n_bounded), damped=solver == "lm")
        self.search = optx.ClassicalTrustRegion() if solver == "lm" else optx.LearningRate(1.0)
        self.verbose = _quiet
