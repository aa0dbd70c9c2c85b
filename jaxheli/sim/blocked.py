"""Blocked simulation: Markov parameters per candidate, block-start states by a short scan.

First-order hold ``x+ = Ad x + B0 u + B1 u+`` becomes a zero-order-hold system with a direct term in the
shifted state ``xi = x - B1 u``: ``xi+ = Ad xi + B' u`` with ``B' = B0 + Ad B1``, and ``y = C xi + C B1 u``
(zero-order hold: ``B1 = 0``, ``xi = x``). Time is cut into blocks of ``L`` samples; from the state ``xi_s``
at a block start the block's outputs are

    y_{s+i} = C Ad^i xi_s + sum_q G_q u_{s+i-q},    i = 1..L,
    G_0 = C B1,  G_q = C Ad^{q-1} B'  (q = 1..L),

a block-Toeplitz map of the ``nu`` inputs ``U_s = [u_s .. u_{s+nu-1}]`` (``nu = L + 1`` under first-order
hold, ``L`` under zero-order hold, where ``G_0 = 0`` is left out), and the next block start is
``xi_{s+L} = Ad^L xi_s + R [u_s .. u_{s+L-1}]``. Only the ``N / L`` block-start states are sequential;
the rest is products shared by the whole population.

Block ``j`` covers the outputs at samples ``jL+1 .. jL+L``, so a restart at a block boundary (the segment
length a multiple of ``L``) acts after the block's last output, the prediction before the restart, as in
the plain scan. Sample 0 (``C x0``) and the ``tail`` samples after the last whole block are evaluated
directly. Arrays here keep the population as the last (fastest) axis, ``[..., P]``.

The block starts are a recursion of ``J`` steps; with ``plan.parallel`` they come from the parallel form
(:func:`jaxheli.sim.parallel.population_states`: a restart is a step whose matrix keeps only the carried states),
sequential depth about ``2 log2 J`` instead of ``J``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from .discretize import Discrete, Hold
from ..model import build_ab
from .population_linalg import discretize_population, pmatmul, pmatvec
from .parallel import population_states

PREFERRED_BLOCK = 16
"""Block length used when the segment length does not decide it (measured fastest on CPU)."""
BLOCK_RANGE = (8, 32)
"""Block lengths :func:`choose_block` considers when it has to divide the segment length."""


class Plan(NamedTuple):
    """Static layout of the blocks on a record of ``n_samples``."""

    n_samples: int
    block: int  # L
    n_inputs: int  # nu: input samples per block (lags q0 .. L)
    n_blocks: int  # J whole blocks: outputs 1 .. J L
    tail: int  # outputs J L + 1 .. N - 1, evaluated directly
    segment: int  # restart interval in samples (0: none), a multiple of L
    foh: bool
    parallel: bool = False  # block starts by the parallel form (jaxheli.sim.parallel), not one after another

    @property
    def first_lag(self) -> int:
        """``q0``: 0 under first-order hold (the direct term ``G_0``), 1 under zero-order hold."""
        return 0 if self.foh else 1

    def restarts(self) -> np.ndarray:
        """``[J]``: whether the state after block ``j`` (sample ``(j+1) L``) restarts from the flight."""
        boundary = (np.arange(self.n_blocks) + 1) * self.block
        if self.segment <= 0:
            return np.zeros(self.n_blocks, bool)
        return boundary % self.segment == 0

    def lag_map(self) -> np.ndarray:
        """``E[i-1, q-q0, l] = [l == i - q]``: which input ``l`` of a block meets lag ``q`` at output ``i``."""
        L, q0, nu = self.block, self.first_lag, self.n_inputs
        i = np.arange(1, L + 1)[:, None, None]
        q = np.arange(q0, L + 1)[None, :, None]
        l = np.arange(nu)[None, None, :]
        return (l == i - q).astype(np.float64)


def choose_block(segment_samples: int, preferred: int = PREFERRED_BLOCK) -> int | None:
    """Block length for a restart interval: ``preferred`` without restarts, else the divisor of the interval
    in :data:`BLOCK_RANGE` nearest to ``preferred`` (the interval itself when it is shorter); ``None`` if
    there is none (a prime interval above the range, say)."""
    if segment_samples <= 0:
        return preferred
    lo, hi = BLOCK_RANGE
    if segment_samples <= hi:
        return segment_samples
    divisors = [d for d in range(lo, hi + 1) if segment_samples % d == 0]
    if not divisors:
        return None
    return min(divisors, key=lambda d: (abs(d - preferred), -d))


def make_plan(n_samples: int, block: int, segment: int, hold: Hold) -> Plan:
    if block < 1:
        raise ValueError(f"block length must be positive, got {block}")
    if segment > 0 and segment % block:
        raise ValueError(f"the segment ({segment} samples) must be a multiple of the block length {block}")
    n_blocks = (n_samples - 1) // block
    foh = hold == "foh"
    nu = block + 1 if foh else block
    return Plan(n_samples, block, nu, n_blocks, n_samples - 1 - n_blocks * block, segment, foh)


class Operators(NamedTuple):
    """Per-candidate block operators, population last."""

    F: Float[Array, "n n P"]  # Ad^L transposed, [b, a, P]: xi+[a] = sum_b F[b, a] xi[b]
    R: Float[Array, "Lm n P"]  # drive of one block: xi+ = F xi + R^T [u_s .. u_{s+L-1}]
    CA: Float[Array, "L k n P"]  # C Ad^i, i = 1..L
    G: Float[Array, "nu k m P"]  # Markov parameters G_q, q = q0..L
    B1: Float[Array, "n m P"]  # x = xi + B1 u (zero under zero-order hold)
    powers: Float[Array, "L1 n n P"]  # Ad^0 .. Ad^L


def population_discrete(thetas: Float[Array, "P 40"], g: float, dt: float, hold: Hold) -> Discrete:
    """Discretised models of a population, laid out population last (``Ad[n, n, P]``...)."""
    A, B = build_ab(thetas, g)
    Ad, B0, B1 = discretize_population(jnp.transpose(A, (1, 2, 0)), jnp.transpose(B, (1, 2, 0)), dt, hold)
    return Discrete(Ad, B0, B1)


def operators(d: Discrete, plan: Plan, idx: np.ndarray) -> Operators:
    """Markov parameters and powers of ``d`` (population last) for blocks of ``plan.block``."""
    L = plan.block
    n, m, P = d.B0.shape
    powers = _powers(d.Ad, L)  # [L+1, n, n, P]: Ad^0 .. Ad^L
    drive = d.B0 + pmatmul(d.Ad, d.B1) if plan.foh else d.B0  # B'
    V = pmatmul(powers[:L], drive)  # Ad^t B', t = 0..L-1: [L, n, m, P]
    G = V[:, idx]
    if plan.foh:
        G = jnp.concatenate([d.B1[idx][None], G])
    return Operators(
        F=jnp.transpose(powers[L], (1, 0, 2)),
        R=V[::-1].transpose(0, 2, 1, 3).reshape(L * m, n, P),  # input l meets Ad^{L-1-l} B'
        CA=powers[1:, idx],
        G=G,
        B1=d.B1,
        powers=powers,
    )


def _powers(Ad: Array, L: int) -> Array:
    """``[Ad^0, ..., Ad^L]`` stacked first, by doubling (log2 L batched products)."""
    eye = jnp.broadcast_to(jnp.eye(Ad.shape[0], dtype=Ad.dtype)[:, :, None], Ad.shape)
    stack = jnp.stack([eye, Ad])  # Ad^0, Ad^1
    while stack.shape[0] <= L:
        top = stack[-1]  # Ad^h, h = len - 1
        more = pmatmul(top, stack[1:])  # Ad^{h+1} .. Ad^{2h}
        # materialise each step: fused into the next, XLA would recompute it per use
        stack = jax.lax.optimization_barrier(jnp.concatenate([stack, more]))
    return stack[: L + 1]


def block_inputs(u: Float[Array, "N m"], plan: Plan) -> Float[Array, "J nu_m"]:
    """Stacked inputs ``U_j = [u_{jL} .. u_{jL+nu-1}]`` of the whole blocks."""
    rows = (np.arange(plan.n_blocks) * plan.block)[:, None] + np.arange(plan.n_inputs)[None, :]
    return u[rows].reshape(plan.n_blocks, plan.n_inputs * u.shape[-1])


def initial_shifted(ops: Operators, x0: Float[Array, "n P"], u: Float[Array, "N m"], plan: Plan) -> Array:
    """``xi_0 = x0 - B1 u_0``."""
    return x0 - pmatvec(ops.B1, u[0][:, None]) if plan.foh else x0


def block_states(
    ops: Operators,
    U: Float[Array, "J nu_m"],
    xi0: Float[Array, "n P"],
    u: Float[Array, "N m"],
    measured_states: Float[Array, "N n"],
    mask: np.ndarray,
    keep_unmeasured: bool,
    plan: Plan,
) -> tuple[Float[Array, "J n P"], Float[Array, "n P"]]:
    """Shifted states ``xi`` at the block starts ``0 .. J-1`` (after any restart) and at ``J L``."""
    n, P = xi0.shape
    L, m = plan.block, u.shape[1]
    if plan.n_blocks == 0:
        return jnp.zeros((0, n, P), xi0.dtype), xi0
    drive = jnp.dot(U[:, : L * m], ops.R.reshape(L * m, n * P)).reshape(plan.n_blocks, n, P)
    restart = plan.restarts()
    if plan.parallel:
        return _parallel_states(ops, drive, xi0, u, measured_states, mask, keep_unmeasured, plan)
    if not restart.any():
        def free(xi, w):
            return pmatvec_t(ops.F, xi) + w, xi

        last, X = jax.lax.scan(free, xi0, drive)
        return X, last
    boundary = (np.arange(plan.n_blocks) + 1) * L
    measured = jnp.asarray(mask)[:, None]
    keep = 1.0 if keep_unmeasured else 0.0

    def step(xi, inp):
        w, r, xm, ub = inp
        nxt = pmatvec_t(ops.F, xi) + w
        shift = pmatvec(ops.B1, ub[:, None]) if plan.foh else 0.0  # x = xi + B1 u
        restarted = jnp.where(measured, xm[:, None], keep * (nxt + shift)) - shift
        return jnp.where(r, restarted, nxt), xi

    inputs = (drive, jnp.asarray(restart), measured_states[boundary].astype(xi0.dtype), u[boundary])
    last, X = jax.lax.scan(step, xi0, inputs)
    return X, last


def _parallel_states(
    ops: Operators,
    drive: Float[Array, "J n P"],
    xi0: Float[Array, "n P"],
    u: Float[Array, "N m"],
    measured_states: Float[Array, "N n"],
    mask: np.ndarray,
    keep_unmeasured: bool,
    plan: Plan,
) -> tuple[Float[Array, "J n P"], Float[Array, "n P"]]:
    """:func:`block_states` by the parallel form. Block ``j`` is the step ``xi -> F xi + w_j``; where it ends in a
    restart, ``xi -> K (F xi + w_j + s_j) + xm_j - s_j`` with ``K`` keeping the unmeasured states (all zero under
    ``reset="zero"``), ``xm_j`` the measured ones and ``s_j = B1 u`` the first-order hold's shift at the boundary."""
    J, L = plan.n_blocks, plan.block
    F = ops.powers[L]  # Ad^L, [n, n, P]
    A = jnp.broadcast_to(F[None], (J,) + F.shape)
    b = drive
    restart = plan.restarts()
    if restart.any():
        boundary = (np.arange(J) + 1) * L
        measured = np.asarray(mask, bool)
        kept = jnp.asarray((~measured) * (1.0 if keep_unmeasured else 0.0), F.dtype)[:, None]  # [n, 1]
        xm = jnp.where(jnp.asarray(measured)[:, None], measured_states[boundary][:, :, None].astype(F.dtype), 0.0)
        shift = pmatvec(ops.B1, u[boundary][:, :, None]) if plan.foh else jnp.zeros_like(b)  # [J, n, P]
        r = jnp.asarray(restart)
        A = jnp.where(r[:, None, None, None], kept[None, :, :, None] * A, A)
        b = jnp.where(r[:, None, None], kept[None] * (b + shift) + xm - shift, b)
    b = b.at[0].add(pmatvec(A[0], xi0))
    states = population_states(A, b)  # xi after blocks 0 .. J-1
    return jnp.concatenate([xi0[None], states[:-1]]), states[-1]


def pmatvec_t(Ft: Float[Array, "n n P"], x: Float[Array, "n P"]) -> Float[Array, "n P"]:
    """``F @ x`` per candidate with ``F`` stored transposed (rows of ``Ft`` are columns of ``F``)."""
    out = Ft[0] * x[0][None, :]
    for b in range(1, Ft.shape[0]):
        out = out + Ft[b] * x[b][None, :]
    return out


def tail_outputs(ops: Operators, xi_last: Float[Array, "n P"], u: Float[Array, "N m"], plan: Plan) -> Array:
    """``[tail, k, P]`` outputs after the last whole block, from its start state."""
    r, L, q0 = plan.tail, plan.block, plan.first_lag
    if r == 0:
        return jnp.zeros((0,) + ops.CA.shape[1:2] + xi_last.shape[1:], xi_last.dtype)
    start = plan.n_blocks * L
    i = np.arange(1, r + 1)[:, None]
    q = np.arange(q0, L + 1)[None, :]
    valid = (i - q >= 0)[..., None]
    shifted = jnp.where(valid, u[start + np.clip(i - q, 0, None)], 0.0)  # [r, nu, m]: u_{s+i-q}
    nq, k, m, P = ops.G.shape
    forced = jnp.dot(shifted.reshape(r, nq * m), ops.G.transpose(0, 2, 1, 3).reshape(nq * m, k * P))
    return pmatvec(ops.CA[:r], xi_last[None]) + forced.reshape(r, k, P)


def toeplitz(ops: Operators, plan: Plan) -> Float[Array, "nu_m L k P"]:
    """The block-Toeplitz map ``T[(l, m), i, k]`` written out (only the materialised outputs need it)."""
    nq, k, m, P = ops.G.shape
    E = jnp.asarray(plan.lag_map(), ops.G.dtype)  # [L, nq, nu]
    T = jnp.einsum("iql,qcap->laicp", E, ops.G)
    return T.reshape(plan.n_inputs * m, plan.block, k, P)


def block_outputs(ops: Operators, X: Float[Array, "J n P"], U: Float[Array, "J nu_m"], plan: Plan) -> Array:
    """All outputs of the whole blocks, ``[P, J, L, k]``, materialised (for :class:`Simulator` outputs)."""
    forced = jnp.einsum("dikp,jd->pjik", toeplitz(ops, plan), U)
    free = jnp.einsum("ikbp,jbp->pjik", ops.CA, X)
    return forced + free


class Blocks(NamedTuple):
    """One population's blocked run: operators, stacked inputs, block-start states ``X`` and the state after
    the last whole block; what the rollout and the Pearson sums both start from."""

    ops: Operators
    U: Float[Array, "J nu_m"]
    u: Float[Array, "N m"]
    x0: Float[Array, "n P"]
    X: Float[Array, "J n P"]
    last: Float[Array, "n P"]
    idx: np.ndarray
    plan: Plan


def run_blocks(
    d: Discrete,
    u: Float[Array, "N m"],
    x0: Float[Array, "n P"],
    measured_states: Float[Array, "N n"],
    mask: np.ndarray,
    keep_unmeasured: bool,
    idx: np.ndarray,
    plan: Plan,
) -> Blocks:
    """The states at every block start of a population (restarts included) and the operators behind them."""
    ops = operators(d, plan, idx)
    U = block_inputs(u, plan)
    X, last = block_states(
        ops, U, initial_shifted(ops, x0, u, plan), u, measured_states, mask, keep_unmeasured, plan
    )
    return Blocks(ops, U, u, x0, X, last, idx, plan)


def blocked_rollout(b: Blocks) -> Float[Array, "P N k"]:
    """Simulated outputs ``[P, N, k]`` of a blocked run, equal to the step-by-step scan up to rounding."""
    P, k = b.x0.shape[1], len(b.idx)
    first = jnp.transpose(b.x0[b.idx])[:, None, :]  # [P, 1, k]
    body = block_outputs(b.ops, b.X, b.U, b.plan).reshape(P, b.plan.n_blocks * b.plan.block, k)
    tail = jnp.transpose(tail_outputs(b.ops, b.last, b.u, b.plan), (2, 0, 1))
    return jnp.concatenate([first, body, tail], axis=1)
