"""Small dense linear algebra for a population laid out last (``[..., n, n, P]``), products only.

XLA on CPU runs a batch of 13 x 13 products far faster as one fused elementwise pass over the population
axis than as a batched dot, and these helpers call no LAPACK: the library's LU runs on the shared CPU
thread pool and can deadlock when several host devices run it at once, which matters once the population
is sharded over devices.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from .discretize import Hold


def pmatmul(a: Float[Array, "*t i j P"], b: Float[Array, "*t j k P"]) -> Float[Array, "*t i k P"]:
    """``a @ b`` per candidate (leading axes broadcast), as one fused sum of ``j`` broadcast products.

    The result is materialised (an optimisation barrier): fused into a consumer that reads each element
    several times, XLA would recompute the whole sum per read.
    """
    a, b = _same_rank(a, b)
    out = a[..., :, 0:1, :] * b[..., 0:1, :, :]
    for j in range(1, a.shape[-2]):
        out = out + a[..., :, j : j + 1, :] * b[..., j : j + 1, :, :]
    return jax.lax.optimization_barrier(out)


def pmatvec(a: Float[Array, "*t i j P"], x: Float[Array, "*t j P"]) -> Float[Array, "*t i P"]:
    """``a @ x`` per candidate."""
    a, x = _same_rank(a, x[..., None, :, :])
    x = x[..., 0, :, :]
    out = a[..., :, 0, :] * x[..., 0:1, :]
    for j in range(1, a.shape[-2]):
        out = out + a[..., :, j, :] * x[..., j : j + 1, :]
    return out


_FEW_SQUARINGS = 6
_MAX_SQUARINGS = 64


def _same_rank(a: Array, b: Array) -> tuple[Array, Array]:
    """Leading unit axes so that both have the same rank (the tests forbid implicit rank promotion)."""
    rank = max(a.ndim, b.ndim)
    return a.reshape((1,) * (rank - a.ndim) + a.shape), b.reshape((1,) * (rank - b.ndim) + b.shape)


def pexpm(M: Float[Array, "n n P"]) -> Float[Array, "n n P"]:
    """Matrix exponential per candidate: Taylor polynomial (Paterson-Stockmeyer) with scaling and squaring.

    The degree (16 in float64, 8 in float32) and the scaled norm bound 1/2 put the truncation error below
    the unit roundoff; the number of squarings is each candidate's own (loops run the population's largest
    and leave the others unchanged; norms beyond 2^63 are not scaled down far enough). Non-finite input
    gives non-finite output, never a hang.
    """
    degree = 16 if M.dtype == jnp.float64 else 8
    norm = jnp.max(jnp.sum(jnp.abs(M), axis=0), axis=0)  # 1-norm per candidate
    ok = jnp.isfinite(norm)
    squarings = jnp.where(ok, jnp.maximum(0.0, jnp.ceil(jnp.log2(jnp.where(ok, norm, 1.0) / 0.5))), 0.0)
    squarings = jnp.minimum(squarings, float(_MAX_SQUARINGS))
    X = M * jnp.exp2(-squarings)[None, None, :]
    E = _taylor(X, degree)
    count = squarings.astype(jnp.int32)[None, None, :]

    def square(E, i):
        return jnp.where(i < count, pmatmul(E, E), E), None

    # static trip counts (reverse-mode differentiable): the few squarings every model in the search box
    # needs, then the rest only when some candidate is far outside it (tau -> 0, say)
    E, _ = jax.lax.scan(square, E, jnp.arange(_FEW_SQUARINGS))
    rest = jnp.arange(_FEW_SQUARINGS, _MAX_SQUARINGS)
    E = jax.lax.cond(jnp.max(count) > _FEW_SQUARINGS, lambda E: jax.lax.scan(square, E, rest)[0], lambda E: E, E)
    return jnp.where(ok[None, None, :], E, jnp.nan)


def _taylor(X: Array, degree: int) -> Array:
    """``sum_{k<=degree} X^k / k!`` by Paterson-Stockmeyer: Horner in ``X^s`` over blocks of ``s`` terms."""
    n = X.shape[0]
    s = int(round(np.sqrt(degree)))
    powers = [jnp.broadcast_to(jnp.eye(n, dtype=X.dtype)[:, :, None], X.shape), X]
    for _ in range(2, s + 1):
        powers.append(pmatmul(powers[-1], X))
    coef = [1.0 / float(np.prod(np.arange(1, k + 1, dtype=np.float64))) for k in range(degree + 1)]
    result = None
    for i in reversed(range(degree // s + 1)):
        block = sum(coef[i * s + j] * powers[j] for j in range(s) if i * s + j <= degree)
        result = block if result is None else pmatmul(result, powers[s]) + block
    return result


def discretize_population(
    A: Float[Array, "n n P"], B: Float[Array, "n m P"], dt: float, hold: Hold
) -> tuple[Array, Array, Array]:
    """``(Ad, B0, B1)``, population last, as :func:`jaxheli.sim.discretize.discretize` computes them."""
    n, m, P = B.shape
    dtype = A.dtype
    if hold == "zoh":
        top = jnp.concatenate([A, B], axis=1)
        M = jnp.concatenate([top, jnp.zeros((m, n + m, P), dtype)], axis=0)
        E = pexpm(M * dt)
        return E[:n, :n], E[:n, n:], jnp.zeros((n, m, P), dtype)
    eye = jnp.broadcast_to(jnp.eye(m, dtype=dtype)[:, :, None], (m, m, P))
    zn = jnp.zeros((m, n, P), dtype)
    zm = jnp.zeros((m, m, P), dtype)
    M = jnp.concatenate(
        [
            jnp.concatenate([A, B, jnp.zeros((n, m, P), dtype)], axis=1),
            jnp.concatenate([zn, zm, eye / dt], axis=1),
            jnp.concatenate([zn, zm, zm], axis=1),
        ],
        axis=0,
    )
    E = pexpm(M * dt)
    gamma1 = E[:n, n : n + m]
    gamma2 = E[:n, n + m :]
    return E[:n, :n], gamma1 - gamma2, gamma2
