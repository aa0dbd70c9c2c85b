"""The paper's cost from Gram matrices of the block inputs: Pearson sums without simulated outputs.

In whole block ``j`` the outputs are ``y_{j,i} = CA_i xi_j + sum_q G_q u_{jL+i-q}`` (see
:mod:`jaxheli.sim.blocked`). Centre the block-start states and the stacked block inputs over the blocks
(``xc_j``, ``Uc_j``) and the measurement (``mc``, and ``mc'`` centred again at each block position ``i``).
Per channel, with ``ybar_i`` the mean output at position ``i``,

    sum y            = J sum_i ybar_i
    sum (y - ybar_i)^2 = sum_i CA_i Sxx CA_i^T + 2 sum_q N_q . G_q + sum_{q,q'} G_q^T K_{q,q'} G_q'
    sum y mc         = sum_i [CA_i (X^T mc')_i + ybar_i sum_j mc_{j,i}] + sum_q G_q . K2_q

where ``Sxx = sum_j xc_j xc_j^T`` (13 x 13 per candidate, states scaled to unit range so that a diverging
but finite state cannot overflow it), ``N_q = sum_i CA_i (X^T Uc)_{i-q}``, and ``K = sum_i
(Uc^T Uc)_{i-q, i-q'}``, ``K2_q = sum_i (Uc^T mc')_{i-q, i}`` are shared by the whole population: the
input Gram is folded along the Toeplitz diagonals once, so each candidate only pays for a quadratic form in
its ``L + 1`` Markov parameters. The one large product is ``[Uc | mc']^T X`` for the whole population.
Sample 0 and the tail after the last whole block are added sample by sample. Centring first keeps the
sums free of the cancellation in ``sum y^2 - (sum y)^2 / N``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from .blocked import Operators, Plan, tail_outputs
from ..cost import flat_from_sums, pearson_from_sums, require_varying
from .population_linalg import pmatmul


def blocked_pearson(sim, thetas: Float[Array, "P 40"], target: Float[Array, "N k"]) -> Float[Array, "P k"]:
    """Pearson's rho per candidate and channel, ``[P, k]``, of a blocked :class:`~jaxheli.Simulator`."""
    require_varying(target)
    ops, U, u, x0, X, last, idx, plan = sim.blocks(thetas)
    target = jnp.asarray(target, X.dtype)
    mc = target - jnp.mean(target, axis=0, keepdims=True)
    m_spread = jnp.sum(mc**2, axis=0)
    extra_y = jnp.concatenate([x0[idx][None], tail_outputs(ops, last, u, plan)])  # [E, k, P]
    extra_m = jnp.concatenate([mc[:1], mc[plan.n_blocks * plan.block + 1 :]])  # [E, k]
    mean, spread, cross = _sums(ops, X, U, mc, extra_y, extra_m, idx, plan)
    count = plan.n_samples
    bad = flat_from_sums(spread, spread / count + mean**2, count) | ~jnp.isfinite(cross)
    rho = pearson_from_sums(cross, spread, m_spread[:, None], bad)  # [k, P]
    return jnp.transpose(rho)


def blocked_cost(sim, thetas: Float[Array, "P 40"], target: Float[Array, "N k"]) -> Float[Array, "P"]:
    """The paper's cost ``sum (1 - rho)^2`` per candidate, from :func:`blocked_pearson`."""
    return jnp.sum((1.0 - blocked_pearson(sim, thetas, target)) ** 2, axis=-1)


def _sums(
    ops: Operators,
    X: Float[Array, "J n P"],
    U: Float[Array, "J D"],
    mc: Float[Array, "N k"],
    extra_y: Float[Array, "E k P"],
    extra_m: Float[Array, "E k"],
    idx: np.ndarray,
    plan: Plan,
) -> tuple[Array, Array, Array]:
    """``(mean, spread, cross)`` per channel and candidate (``[k, P]``) over the whole record."""
    J, L, nu = plan.n_blocks, plan.block, plan.n_inputs
    count = plan.n_samples
    extra_sum = _lead_sum(extra_y)
    extra_cross = jnp.einsum("ekp,ek->kp", extra_y, extra_m)
    if J == 0:
        mean = extra_sum / count
        return mean, _lead_sum((extra_y - mean[None]) ** 2), extra_cross
    CA, G = ops.CA, ops.G  # [L, k, n, P], [nq, k, m, P]
    nq, k, m, P = G.shape
    n = X.shape[1]
    E = jnp.asarray(plan.lag_map(), X.dtype)  # [L, nq, nu]
    # shared by the population
    Mb = mc[1 : J * L + 1].reshape(J, L * k)
    Mcol = jnp.sum(Mb, axis=0)  # [L k]
    Mb = Mb - Mcol[None] / J  # centred at each block position too
    Ubar = jnp.mean(U, axis=0)
    Uc = U - Ubar[None]
    Suu = (Uc.T @ Uc).reshape(nu, m, nu, m)
    K = jnp.einsum("iql,irs,lasb->qarb", E, E, Suu).reshape(nq * m, nq * m)
    K2 = jnp.einsum("iql,laic->qca", E, (Uc.T @ Mb).reshape(nu, m, L, k))  # [nq, k, m]
    Ushift = jnp.einsum("iql,la->iqa", E, Ubar.reshape(nu, m)).reshape(L, nq * m)
    # per candidate
    Gflat = jax.lax.optimization_barrier(G.transpose(0, 2, 1, 3).reshape(nq * m, k * P))  # rows (q, m)
    Gram = jnp.dot(jnp.concatenate([Uc, Mb], axis=1).T, X.reshape(J, n * P)).reshape(nu * m + L * k, n, P)
    Sxu = Gram[: nu * m].reshape(nu, m, n, P).transpose(0, 2, 1, 3)  # [nu, n, m, P]: sum_j x_j U_j^T
    Sxm = Gram[nu * m :].reshape(L, k, n, P)  # sum_j mc'_{j,i} x_j
    xbar = _lead_sum(X) / J  # [n, P]
    scale = jnp.max(jnp.abs(X), axis=0)
    scale = jnp.where(scale > 0, scale, 1.0)
    Sxx = _scaled_gram(X, xbar, 1.0 / scale, plan.parallel)  # [n, n, P], states in units of their largest value
    ybar = _contract(CA, xbar[None, None]) + jnp.dot(Ushift, Gflat).reshape(L, k, P)
    CAs = CA * scale[None, None]
    Qxx = _lead_sum(_contract(pmatmul(CAs, Sxx), CAs))  # [k, P]
    N = _lagged_cross(ops.powers, Sxu, idx, plan)  # [nq, k, m, P]
    Quu = _lead_sum((jnp.dot(K, Gflat) * Gflat).reshape(nq * m, k, P))
    Qxu = _lead_sum(jnp.sum(N * G, axis=2))
    Sym = _lead_sum(_contract(CA, Sxm) + ybar * Mcol.reshape(L, k, 1)) + jnp.einsum("qcap,qca->cp", G, K2)
    mean = (J * _lead_sum(ybar) + extra_sum) / count
    spread = Qxx + 2.0 * Qxu + Quu + J * _lead_sum((ybar - mean[None]) ** 2) + _lead_sum((extra_y - mean[None]) ** 2)
    return mean, spread, Sym + extra_cross


def _lagged_cross(powers: Array, Sxu: Array, idx: np.ndarray, plan: Plan) -> Float[Array, "nq k m P"]:
    """``N_q = sum_i C Ad^i Sxu_{i-q} = C Ad^q sum_l Ad^l Sxu_l`` (``l`` over ``i - q`` in the block).

    Two fused per-candidate products and one shared 0/1 matrix of partial sums, instead of a product for
    every (output, lag) pair.
    """
    L, q0, nu = plan.block, plan.first_lag, plan.n_inputs
    n, m, P = Sxu.shape[1:]
    moved = pmatmul(powers[:nu], Sxu)  # Ad^l Sxu_l
    q = np.arange(q0, L + 1)[:, None]
    l = np.arange(nu)[None, :]
    window = ((l >= np.where(q == 0, 1, 0)) & (l <= L - q)).astype(np.float64)  # [nq, nu]
    M = jnp.dot(jnp.asarray(window, Sxu.dtype), moved.reshape(nu, -1)).reshape(-1, n, m, P)
    return pmatmul(powers[q0:, idx], M)


def _contract(a: Float[Array, "*t n P"], b: Float[Array, "*t n P"]) -> Float[Array, "*t P"]:
    """``sum_a a[..., a, :] b[..., a, :]`` as one fused sum over the short state axis."""
    out = a[..., 0, :] * b[..., 0, :]
    for i in range(1, a.shape[-2]):
        out = out + a[..., i, :] * b[..., i, :]
    return out


def _lead_sum(a: Array) -> Array:
    """Sum over the first axis as a matrix-vector product (XLA on CPU reduces leading axes slowly)."""
    return jnp.dot(jnp.ones(a.shape[0], a.dtype), a.reshape(a.shape[0], -1)).reshape(a.shape[1:])


_GRAM_UNROLL = 16


def _scaled_gram(X: Float[Array, "J n P"], centre: Array, inv_scale: Array, parallel: bool = False
                 ) -> Float[Array, "n n P"]:
    """``sum_j xs_j xs_j^T`` per candidate with ``xs = (x - centre) * inv_scale``, population last.

    A loop over chunks of blocks, each chunk's outer products summed in one fused elementwise pass (XLA
    on CPU runs this several times faster than a batched dot with 13 x 13 results); with ``parallel`` (the block
    starts' parallel form, no loop in time) one batched product at full precision.
    """
    if parallel:
        xs = (X - centre[None]) * inv_scale[None]
        return jnp.einsum("jap,jbp->abp", xs, xs, precision=jax.lax.Precision.HIGHEST)
    J, n, P = X.shape
    c = min(_GRAM_UNROLL, J)
    whole = (J // c) * c

    def outer_sum(acc, chunk):
        chunk = jax.lax.optimization_barrier(chunk)  # keep the slicing out of the fused sum
        for t in range(chunk.shape[0]):
            y = (chunk[t] - centre) * inv_scale
            acc = acc + y[:, None, :] * y[None, :, :]
        return acc, None

    acc = jnp.zeros((n, n, P), X.dtype)
    if whole:
        acc, _ = jax.lax.scan(outer_sum, acc, X[:whole].reshape(J // c, c, n, P))
    if whole < J:
        acc, _ = outer_sum(acc, X[whole:])
    return acc
