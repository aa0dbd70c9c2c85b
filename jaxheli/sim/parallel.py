"""Parallel-in-time evaluation of an affine recursion: the states after every step as prefix compositions of the steps.

A step ``x -> A_m x + b_m`` (column vectors) composed with the next is again a step,

    (A_1, b_1) then (A_2, b_2) = (A_2 A_1, A_2 b_1 + b_2),

(row vectors, ``x -> x A_m + b_m``: ``(A_1 A_2, b_1 A_2 + b_2)``), and composition is associative, so the states
``x_1 .. x_L`` from ``x_0 = 0`` are the prefix compositions of the ``L`` steps: ``jax.lax.associative_scan``
forms them in about ``2 log2 L`` rounds of batched products (about ``2 L`` compositions in all) instead of ``L``
steps one after another. A start ``x_0`` other than zero is folded into the first step's ``b``; a restart (a
step that starts afresh, or keeps only some states) is a step whose ``A`` is zero or a projection of the usual one.

Each step's matrix is materialised (``[L, n, n, ...]``), so memory bounds the form
(:data:`jaxheli.sim.forms.MAX_PARALLEL_ELEMENTS`). The values equal the plain scan's up to rounding: the same sums in
another order (``tests/test_parallel.py`` states and tests the bound). Products run at full precision
(``Precision.HIGHEST``) so that a GPU does not round float32 operands to TensorFloat-32.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._types import Array, Float

HIGHEST = jax.lax.Precision.HIGHEST


def row_states(
    A: Float[Array, "L n n"], b: Float[Array, "L *batch n"], reverse: bool = False
) -> Float[Array, "L *batch n"]:
    """The states ``x_{m+1} = x_m A_m + b_m`` (row vectors; ``*batch``: runs sharing the matrices) after each of the
    ``L`` steps from ``x_0 = 0``. ``reverse``: the steps run from the last to the first, ``x_m = x_{m+1} A_m + b_m``
    from ``x_L = 0``, and row ``m`` holds ``x_m``."""

    def compose(first: tuple[Array, Array], then: tuple[Array, Array]) -> tuple[Array, Array]:
        A1, b1 = first
        A2, b2 = then
        return (jnp.matmul(A1, A2, precision=HIGHEST),
                jnp.einsum("l...i,lij->l...j", b1, A2, precision=HIGHEST) + b2)

    return jax.lax.associative_scan(compose, (A, b), reverse=reverse)[1]


def population_states(A: Float[Array, "L n n P"], b: Float[Array, "L n P"]) -> Float[Array, "L n P"]:
    """The states ``x_{m+1} = A_m x_m + b_m`` of every candidate (population last, as
    :mod:`jaxheli.sim.blocked` lays them out) after each of the ``L`` steps from ``x_0 = 0``."""

    def compose(first: tuple[Array, Array], then: tuple[Array, Array]) -> tuple[Array, Array]:
        A1, b1 = first
        A2, b2 = then
        return (jnp.einsum("lijp,ljkp->likp", A2, A1, precision=HIGHEST),
                jnp.einsum("lijp,ljp->lip", A2, b1, precision=HIGHEST) + b2)

    return jax.lax.associative_scan(compose, (A, b))[1]
