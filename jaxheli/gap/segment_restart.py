"""Each segment's restart state re-estimated from the segment's own readings, with a hand-written tangent.

The correction is ``c_s = Phi d_s``, ``d_s = A_s^-1 Phi' W r_s``, ``A_s = Phi' W Phi + P^-1`` over the segment's
samples (``Phi_j = H F^j``). Forward-mode differentiation of that formula carries the tangent of every ``Phi_j``
(``segment x k x n`` numbers per free parameter) through the contractions; the tangent written here propagates
vectors instead: a forward recursion for the free response's change ``dPhi_j d_s`` and a backward (adjoint)
recursion for ``sum_j dPhi_j' W e_sj`` (``e``: the residual after the correction), the rest contractions with the
primal ``Phi``. Same numbers (``tests/test_segment_restart.py`` compares it with JAX's own tangent of the plain
formula), in about half the time of forward-mode differentiation through the formula.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp

from .._types import Array, Float


def _parts(residual, F, H, P, noise_var, anchor, segment):
    """The correction ``c[s, j, k]`` and what its tangent reuses: ``F^j`` (``j = 1 .. segment``), ``Phi``, the
    weights, the seen-sample mask, each segment's information matrix, ``P^-1``, the padded residual, ``d``."""
    m, k = residual.shape
    count = -(-m // segment)

    def power(Fj, _):
        Fj = F @ Fj
        return Fj, Fj

    _, powers = jax.lax.scan(power, jnp.eye(F.shape[0], dtype=F.dtype), None, length=segment)
    phi = jnp.einsum("ka,jab->jkb", H, powers)
    w = 1.0 / noise_var
    seen = (jnp.arange(count * segment) < m).reshape(count, segment).astype(residual.dtype)
    last = m - (count - 1) * segment
    gram = jnp.einsum("jka,k,jkb->ab", phi, w, phi)
    gram_last = jnp.einsum("jka,k,jkb->ab", phi[:last], w, phi[:last])
    p_inv = jnp.linalg.inv(P)
    info = jnp.concatenate([jnp.broadcast_to(gram, (count - 1, *gram.shape)), gram_last[None]]) + p_inv[None]
    info = info.at[0].add(jnp.diag(anchor))
    r = _pad(residual, count, segment)
    d = jnp.linalg.solve(info, jnp.einsum("jka,k,sjk->sa", phi, w, r)[..., None])[..., 0]
    return jnp.einsum("jka,sa->sjk", phi, d), (powers, phi, w, seen, info, p_inv, r, d)


def _pad(x: Float[Array, "M k"], count: int, segment: int) -> Float[Array, "S J k"]:
    """``x`` cut into ``count`` segments of ``segment`` samples, the last padded with zeros."""
    return jnp.zeros((count * segment, x.shape[1]), x.dtype).at[: x.shape[0]].set(x).reshape(count, segment, -1)


@functools.partial(jax.custom_jvp, nondiff_argnums=(6,))
def restart_correction(
    residual: Float[Array, "M k"], F: Float[Array, "n n"], H: Float[Array, "k n"], P: Float[Array, "n n"],
    noise_var: Float[Array, "k"], anchor: Float[Array, "n"], segment: int,
) -> Float[Array, "M k"]:
    """Each segment's restart state re-estimated from the segment's own readings: the change of its predicted
    output states (``residual[m]``: readings minus prediction ``m + 1`` samples after the first restart, a restart
    every ``segment`` samples) when the restart state moves by the least-squares ``d`` of
    ``sum_j |r_j - H F^j d|^2 / noise_var + d' P^-1 d`` (``P``: the filter's covariance of the restart state, the
    prior; ``j = 1 .. segment`` samples after it; the first segment's prior information gains ``diag(anchor)``, a
    constant: states known at the record's start, such as a bias walk's zero). The free response of the linear part is exact; airframe terms
    (drag, rotor speed) are held where the filter's restart put them. Restarts from a filter of the past alone
    leave errors that grow along the segment, and a least-squares fit of the dynamics then bends the model to
    shrink them (on effect-free flights of the model class it moved the parameters far from the truth); with the
    restart estimated from the segment too, the residual is what the dynamics cannot explain. The first segment,
    started from the first readings, gets the same prior."""
    c, _ = _parts(residual, F, H, P, noise_var, anchor, segment)
    return c.reshape(-1, residual.shape[1])[: residual.shape[0]]


@restart_correction.defjvp
def _restart_correction_jvp(segment, primals, tangents):
    """``dc = dPhi d + Phi dd`` with ``dd = A^-1 (sum_j dPhi_j' W e_j + Phi_j' dW e_j + Phi_j' W (dr_j - dPhi_j d)
    + P^-1 dP P^-1 d)`` (``e_j``: residual after the correction, zero on padding), by recursions over vectors; the
    anchor is a constant (its tangent ignored)."""
    residual, F, H, P, noise_var, anchor = primals
    d_res, dF, dH, dP, d_var, _ = tangents
    m, k = residual.shape
    c, (powers, phi, w, seen, info, p_inv, r, d) = _parts(residual, F, H, P, noise_var, anchor, segment)
    count = d.shape[0]
    e = r - seen[..., None] * c
    after = jnp.einsum("jab,sb->jsa", powers, d)
    before = jnp.concatenate([d[None], after[:-1]])

    def forward(dx, u):
        dx = dx @ F.T + u
        return dx, dx

    def backward(lam, g):
        lam = g + lam @ F
        return lam, lam

    _, d_after = jax.lax.scan(forward, jnp.zeros_like(d), before @ dF.T)
    d_free = jnp.einsum("ka,jsa->sjk", dH, after) + jnp.einsum("ka,jsa->sjk", H, d_after)
    _, lam = jax.lax.scan(backward, jnp.zeros_like(d), jnp.einsum("ka,k,sjk->jsa", H, w, e), reverse=True)
    drive = lam @ dF + jnp.einsum("ka,k,sjk->jsa", dH, w, e) @ F
    adjoint, _ = jax.lax.scan(backward, jnp.zeros_like(d), drive, reverse=True)
    rhs = (adjoint + jnp.einsum("jka,k,sjk->sa", phi, w, _pad(d_res, count, segment) - seen[..., None] * d_free)
           - jnp.einsum("jka,k,sjk->sa", phi, d_var / noise_var**2, e) + d @ (p_inv @ dP @ p_inv).T)
    dd = jnp.linalg.solve(info, rhs[..., None])[..., 0]
    dc = d_free + jnp.einsum("jka,sa->sjk", phi, dd)
    return c.reshape(-1, k)[:m], dc.reshape(-1, k)[:m]
