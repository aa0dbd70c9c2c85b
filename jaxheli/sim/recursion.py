"""A linear recursion with constant matrices, ``x_{m+1} = x_m M + v_m G``, with a hand-written tangent.

Every run of the least-squares engines' simulations is such a recursion (row vectors: ``M = Ad'`` and the sticks
through ``G = [B0 B1]'`` forward, ``M = G = Ad`` for an adjoint pass run backwards). JAX's own tangent of the
``lax.scan`` carries each tangent's ``dM`` and ``dG`` products inside the sequential loop; the tangent of a
recursion is the same recursion, though,

    dx_{m+1} = dx_m M + [x_m, v_m] [dM; dG] + dv_m G,

so its drive is formed for every step at once, outside the loop, in one product (a Jacobian's columns, batched by
``vmap``, in one matrix product), and the loop advances all the tangents with the one matrix ``M``, keeping only
the ``keep`` columns of each state. Same numbers (``tests/test_recursion.py``). Measured (2-core CPU, 36 tangents,
the 8,001-sample default flight): the output-error residuals' Jacobian took 158 / 188 / 181 ms over 5-s runs, 20-s runs
and one run, against 157 / 243 / 517 ms with JAX's tangent of the scan.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero

from .._types import Array, Float


def _scan(M, drive, x0, reverse, keep):
    """The states (their ``keep`` columns) after each step of ``x_{m+1} = x_m M + drive[m]``, and all columns."""

    def step(x, d):
        x = x @ M + d
        return x, (x if keep is None else x[..., keep], x)

    return jax.lax.scan(step, x0, drive, reverse=reverse)[1]


@functools.partial(jax.custom_jvp, nondiff_argnums=(4, 5))
def linear_recursion(
    M: Float[Array, "n n"], G: Float[Array, "c n"], v: Float[Array, "L *batch c"], x0: Float[Array, "*batch n"],
    reverse: bool = False, keep: tuple[int, ...] | None = None,
) -> Float[Array, "L *batch k"]:
    """The states ``x_{m+1} = x_m M + v[m] G`` after each of the ``L`` steps, from ``x0`` (``*batch``: runs
    advanced side by side), their ``keep`` columns (all with ``None``). ``reverse``: the steps run from the last
    to the first, ``out[m] = out[m + 1] M + v[m] G`` with ``out[L] = x0`` (an adjoint pass; ``out[0]`` is its
    final state)."""
    return _scan(M, v @ G, x0, reverse, keep)[0]


@functools.partial(linear_recursion.defjvp, symbolic_zeros=True)
def _linear_recursion_jvp(reverse, keep, primals, tangents):
    """The recursion again, ``M`` its matrix and ``[x_before, v] [dM; dG] + dv G`` its drive, formed for all steps
    at once (``x_before``: the state each step starts from)."""
    M, G, v, x0 = primals
    dM, dG, dv, dx0 = (jnp.zeros(t.aval.shape, t.aval.dtype) if isinstance(t, SymbolicZero) else t
                       for t in tangents)
    out, states = _scan(M, v @ G, x0, reverse, keep)
    first = x0[None]
    before = jnp.concatenate([states[1:], first]) if reverse else jnp.concatenate([first, states[:-1]])
    drive = jnp.concatenate([before, v], axis=-1) @ jnp.concatenate([dM, dG])
    if not isinstance(tangents[2], SymbolicZero):
        drive = drive + dv @ G
    return out, _scan(M, drive, dx0, reverse, keep)[0]
