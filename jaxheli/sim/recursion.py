"""A linear recursion with constant matrices, ``x_{m+1} = c_m x_m M + v_m G``, with a hand-written tangent.

Every run of the least-squares engines' simulations is such a recursion (row vectors: ``M = Ad'`` and the sticks
through ``G = [B0 B1]'`` forward, ``M = G = Ad`` for an adjoint pass run backwards). JAX's own tangent of the
``lax.scan`` carries each tangent's ``dM`` and ``dG`` products inside the sequential loop; the tangent of a
recursion is the same recursion, though,

    dx_{m+1} = dx_m M + [x_m, v_m] [dM; dG] + dv_m G,

so the part ``[x_m, v_m] [dM; dG]`` of its drive is formed for every step at once, outside the loop, in one product
(a Jacobian's columns, batched by ``vmap``, in one matrix product, laid out as the loop reads it), and the loop
advances all the tangents with the one matrix ``M``, adding ``dv_m G`` inside (formed outside, the vmapped ``dv G``
comes out in the tangents-first layout and the sum moves twice between layouts), keeping only the ``keep`` columns
of each state. The step's carry ``c_m`` (1 by default) cuts the recursion where it is 0: one recursion over a record
holds several runs, each started afresh (:mod:`jaxheli.sim.shooting`). The numbers are JAX's own tangent's
(``tests/test_recursion.py``); the Jacobian costs about the same as with JAX's tangent over short runs and a
fraction of it over long ones, where JAX's grows with the run length.

Both the recursion and its tangent run in the form :func:`jaxheli.sim.forms.choose_form` picks (``form``): the plain
scan, or the parallel form (:func:`jaxheli.sim.parallel.row_states`, the steps' matrices ``carry[m] M`` composed in
about ``2 log2 L`` rounds), the same numbers up to rounding.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from jax.custom_derivatives import SymbolicZero

from .._types import Array, Float
from .forms import TimeForm, choose_form
from .parallel import HIGHEST, row_states


def _scan(M, drive, carry, x0, reverse, keep, extra=None, states=False):
    """The states (their ``keep`` columns) after each step of ``x_{m+1} = carry[m] x_m M + drive[m]`` (``+ v[m] G``
    with ``extra = (v, G)``, the product formed inside the loop); with ``states``, all their columns too."""

    def step(x, inputs):
        d, c, *more = inputs
        x = c * (x @ M) + d + (more[0] @ extra[1] if more else 0.0)
        kept = x if keep is None else x[..., keep]
        return x, ((kept, x) if states else kept)

    xs = (drive, carry) if extra is None else (drive, carry, extra[0])
    return jax.lax.scan(step, x0, xs, reverse=reverse)[1]


def linear_recursion(
    M: Float[Array, "n n"], G: Float[Array, "c n"], v: Float[Array, "L *batch c"], x0: Float[Array, "*batch n"],
    reverse: bool = False, keep: tuple[int, ...] | None = None, carry: Float[Array, " L"] | None = None,
    form: TimeForm = "auto",
) -> Float[Array, "L *batch k"]:
    """The states ``x_{m+1} = carry[m] x_m M + v[m] G`` after each of the ``L`` steps, from ``x0`` (``*batch``: runs
    advanced side by side), their ``keep`` columns (all with ``None``). ``reverse``: the steps run from the last
    to the first, ``out[m] = carry[m] out[m + 1] M + v[m] G`` with ``out[L] = x0`` (an adjoint pass; ``out[0]`` is
    its final state). ``carry`` (default 1 at every step; not differentiated): 0 where a step starts afresh.
    ``form``: ``"scan"``, ``"parallel"`` or ``"auto"`` (:func:`jaxheli.sim.forms.choose_form`)."""
    carry = jnp.ones(v.shape[:1], M.dtype) if carry is None else carry.astype(M.dtype)
    n = M.shape[-1]
    parallel = choose_form("recursion", v.shape[0], form, elements=v.shape[0] * n * n) == "parallel"
    return _recursion(M, G, v, x0, jax.lax.stop_gradient(carry), reverse, keep, parallel)


@functools.partial(jax.custom_jvp, nondiff_argnums=(5, 6, 7))
def _recursion(M, G, v, x0, carry, reverse, keep, parallel):
    if parallel:
        return _parallel(M, v @ G, carry, x0, reverse, keep)
    return _scan(M, v @ G, _per_step(carry, x0), x0, reverse, keep)


def _parallel(M, drive, carry, x0, reverse, keep, extra=None, states=False):
    """:func:`_scan`'s values by the parallel form: the steps ``(carry[m] M, drive[m])``, the start ``x0`` folded into
    the first step's drive (the last step's with ``reverse``)."""
    if extra is not None:
        drive = drive + jnp.matmul(extra[0], extra[1], precision=HIGHEST)
    first = -1 if reverse else 0
    drive = drive.at[first].add(carry[first] * jnp.matmul(x0, M, precision=HIGHEST))
    x = row_states(carry[:, None, None] * M[None], drive, reverse)
    kept = x if keep is None else x[..., keep]
    return (kept, x) if states else kept


def _per_step(carry: Float[Array, " L"], x0: Float[Array, "*batch n"]) -> Float[Array, "L *batch 1"]:
    """Each step's carry, broadcast against a state."""
    return carry.reshape(carry.shape + (1,) * x0.ndim)


@functools.partial(_recursion.defjvp, symbolic_zeros=True)
def _recursion_jvp(reverse, keep, parallel, primals, tangents):
    """The recursion again, ``M`` its matrix and ``carry [x_before] dM + v dG + dv G`` its drive, formed for all steps
    at once (``x_before``: the state each step starts from), in the recursion's own form."""
    M, G, v, x0, carry = primals
    dM, dG, dv, dx0 = (jnp.zeros(t.aval.shape, t.aval.dtype) if isinstance(t, SymbolicZero) else t
                       for t in tangents[:4])
    c = _per_step(carry, x0)
    if parallel:
        out, states = _parallel(M, v @ G, carry, x0, reverse, keep, states=True)
    else:
        out, states = _scan(M, v @ G, c, x0, reverse, keep, states=True)
    first = x0[None]
    before = jnp.concatenate([states[1:], first]) if reverse else jnp.concatenate([first, states[:-1]])
    drive = jnp.concatenate([c * before, v], axis=-1) @ jnp.concatenate([dM, dG])
    extra = None if isinstance(tangents[2], SymbolicZero) else (dv, G)
    if parallel:
        return out, _parallel(M, drive, carry, dx0, reverse, keep, extra)
    return out, _scan(M, drive, c, dx0, reverse, keep, extra)
