"""A forward-mode Jacobian whose memory is bounded: its columns computed a chunk of directions at a time.

A residual vector of ``m`` entries (a record's samples times its channels) carries, for every direction its tangent
is pushed along, the tangents of the simulation's states and outputs: a vmap over all ``n`` directions at once
holds about ``n`` times a few simulations' worth of arrays (a 30-minute record at 250 Hz: tens of GB). Past
:data:`TANGENT_BYTES` the directions go ``lax.map``-ped in chunks (each chunk vmapped), so the memory of the
tangents stays bounded whatever the record's length and only the Jacobian itself (``n x m``) grows with it; a record
of ordinary length takes every direction at once, as ``jax.jacfwd`` does.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from .._types import Array, Float

TANGENT_BYTES = 1 << 31
"""Budget, bytes, of the tangents pushed at once: about :data:`_ARRAYS_PER_RESIDUAL` arrays of the residuals' size
per direction. Each chunk is another pass of the simulation's scans over the record, so fewer, larger chunks are
faster: a 30-minute record at 250 Hz takes 9 directions at a time (4 passes; 4 at a time, 9 passes, made its polish
1.5x slower)."""
_ARRAYS_PER_RESIDUAL = 8
"""Residual-sized float64 arrays a direction's tangent holds at its peak (states, outputs, the runs' sums), an
estimate on the safe side: 13 states for every 4 to 8 channels, over up to three passes."""


def chunk_size(n: int, m: int, itemsize: int = 8) -> int:
    """Directions pushed at once for ``n`` directions and ``m`` residuals of ``itemsize`` bytes: all ``n`` while
    their tangents fit :data:`TANGENT_BYTES`, else as many as fit (at least one)."""
    per_direction = max(m, 1) * itemsize * _ARRAYS_PER_RESIDUAL
    return int(max(1, min(n, TANGENT_BYTES // per_direction)))


def jacobian_transpose(
    jvp: Callable[[Float[Array, " n"]], Float[Array, " m"]], n: int, m: int, dtype: jnp.dtype
) -> Float[Array, "n m"]:
    """``J^T`` of a linear map ``jvp(v) = J v`` on ``n`` unknowns with ``m`` residuals, one row per unknown, the
    directions pushed :func:`chunk_size` at a time."""
    basis = jnp.eye(n, dtype=dtype)
    chunk = chunk_size(n, m, jnp.dtype(dtype).itemsize)
    return jax.vmap(jvp)(basis) if chunk >= n else jax.lax.map(jvp, basis, batch_size=chunk)


def residuals_and_jacobian(
    fn: Callable[[Float[Array, " n"]], Float[Array, " m"]], x: Float[Array, " n"]
) -> tuple[Float[Array, " m"], Float[Array, "m n"]]:
    """``fn(x)`` and its Jacobian ``[m, n]`` by forward mode, within the tangents' memory budget (see the module)."""
    r, jvp = jax.linearize(fn, x)
    return r, jacobian_transpose(jvp, x.shape[0], r.shape[0], x.dtype).T
