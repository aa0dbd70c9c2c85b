"""Steady-state Kalman filter of the plant plus a first-order gust model and wandering output biases (random walks
that may revert): the filter-error idea.

The wind on u, v, w is first-order Gauss-Markov (``wind+ = rho wind + sqrt(1 - rho^2) sigma white``,
``rho = exp(-dt / tau)``), the same process :func:`jaxheli.piloted_flight` flies; each output channel carries a bias
that walks and reverts (``b+ = e^(-rate dt) b + walk sqrt(dt) white``, the ``walk`` and ``revert`` groups of the bias
candidate). Augmenting the state
with both, the steady-state predicted covariance solves the filter Riccati equation; it is computed by the
structure-preserving doubling algorithm (a fixed number of doublings, so jit/vmap friendly), differentiated
implicitly (a Stein equation for the tangent).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._types import Array, Float
from ..effects.plant import GUST_STATES, Plant

_DOUBLINGS = 30
"""Doublings of the Riccati solve (``2^30`` filter steps): the bias states' modes, held by their floor alone, sit
``1e-6`` inside the unit circle; 30 doublings bring their covariance within 1e-9 (relative) of scipy's DARE."""
_FLOOR = 1e-12
"""Process-noise variance floor on every state: keeps unstable modes reachable, so the doubling converges."""
_BIAS_FLOOR = 1e-12
"""Process-noise variance floor of each bias state, as a fraction of its channel's noise variance: a bias gain near
1e-6 per sample, so that with no walk the filter is the plant's alone to a part in 1e4 over 100 s at 100 Hz, and the
closed loop stays far enough inside the unit circle for the doubling and the tangent's Stein equation."""


def _doubling(
    F: Float[Array, "n n"], H: Float[Array, "k n"], Q: Float[Array, "n n"], R: Float[Array, "k k"]
) -> Float[Array, "n n"]:
    """Stabilising solution of the filter Riccati equation by :data:`_DOUBLINGS` doublings (needs ``R`` > 0)."""
    n = F.shape[0]
    eye = jnp.eye(n, dtype=F.dtype)

    def double(_, c):
        A, G, X = c
        W = eye + G @ X
        AW = jnp.linalg.solve(W.T, A.T).T  # A W^-1
        return AW @ A, G + AW @ G @ A.T, X + A.T @ X @ jnp.linalg.solve(W, A)

    G0 = H.T @ jnp.linalg.solve(R, H)
    _, _, P = jax.lax.fori_loop(0, _DOUBLINGS, double, (F.T, G0, Q))
    return 0.5 * (P + P.T)


@jax.custom_jvp
def riccati(
    F: Float[Array, "n n"], H: Float[Array, "k n"], Q: Float[Array, "n n"], R: Float[Array, "k k"]
) -> Float[Array, "n n"]:
    """Stabilising ``P = F P F' - F P H' (H P H' + R)^-1 H P F' + Q`` by doubling (needs ``R`` > 0).

    Its tangent is the implicit one (:func:`_riccati_jvp`): one Stein equation instead of the doubling's
    differentiated iterations, which were half of the diagnosis's Levenberg-Marquardt Jacobian."""
    return _doubling(F, H, Q, R)


@riccati.defjvp
def _riccati_jvp(primals: tuple[Array, ...], tangents: tuple[Array, ...]) -> tuple[Array, Array]:
    """``dP = A dP A' + W``: with ``L = P H' S^-1`` (``S = H P H' + R``), ``M = P - L H P`` and ``A = F (I - L H)``,
    ``W = dF M F' + F M dF' + F (L dR L' - M dH' L' - L dH M) F' + dQ``, solved through ``I - A (x) A``."""
    F, H, Q, R = primals
    dF, dH, dQ, dR = tangents
    P = _doubling(F, H, Q, R)
    L = jnp.linalg.solve(H @ P @ H.T + R, H @ P).T
    M = P - L @ H @ P
    A = F - F @ L @ H
    FM = F @ M
    W = dF @ FM.T + FM @ dF.T + F @ (L @ dR @ L.T - M @ dH.T @ L.T - L @ dH @ M) @ F.T + dQ
    n = F.shape[0]
    dP = jnp.linalg.solve(jnp.eye(n * n, dtype=F.dtype) - jnp.kron(A, A), W.reshape(-1)).reshape(n, n)
    return P, 0.5 * (dP + dP.T)


def gust_filter(
    plant: Plant, noise_var: Float[Array, "k"], track: float = 0.0, walks: bool = True
) -> tuple[Array, Array, Array, Array]:
    """``(F, H, K, P)``: augmented transition ``[x, wind, bias]``, its output matrix ``[C, 0, I]`` (of the output
    states), steady-state filter gain and the covariance of the updated state ``z|k`` (the error of a restart from it).
    ``walks`` (static) ``False`` leaves the bias states out (``[x, wind]``, ``[C, 0]``): for a plant whose walks are
    all zero, where they would only carry their floor.

    ``plant``'s ``gust`` group gives sigma (m/s), tau (s) and a cut ``c`` of ``track`` (to ``track e^-|c|``), its
    ``walk`` group each output bias's walk intensity (the channel's unit per sqrt(s)) and its ``revert`` group their
    reversion rate (1/s);
    ``noise_var`` is each output's measurement noise variance. Each measured state carries process noise of
    variance ``track^2`` times its channel's noise variance per sample (how closely the filter
    follows the measurements rather than the model), every state a ``1e-12`` floor (harmless beside the
    noise), each bias ``walk^2 dt`` over a floor of :data:`_BIAS_FLOOR` times its noise variance.
    The update is ``z|k = z|k-1 + K (y - H z|k-1)`` on the output states.
    """
    sigma, tau, cut = plant.group("gust")
    track = track * jnp.exp(-jnp.abs(cut))
    rho = jnp.exp(-plant.dt / (jnp.abs(tau) + 1e-6))
    rho_bias = jnp.exp(-jnp.abs(plant.group("revert")[0]) * plant.dt)
    n, m, k = plant.Ad.shape[0], len(GUST_STATES), plant.C.shape[0]
    b = k if walks else 0
    F = jnp.block([[plant.Ad, plant.E, jnp.zeros((n, b))], [jnp.zeros((m, n)), rho * jnp.eye(m), jnp.zeros((m, b))],
                   [jnp.zeros((b, n + m)), rho_bias * jnp.eye(b)]])
    H = jnp.concatenate([plant.C, jnp.zeros((k, m)), jnp.eye(k, b)], axis=1)
    q = jnp.concatenate([track**2 * (plant.C.T @ noise_var) + _FLOOR, jnp.full(m, sigma**2 * (1.0 - rho**2) + _FLOOR),
                         (plant.group("walk") ** 2 * plant.dt + _BIAS_FLOOR * noise_var)[:b]])
    R = jnp.diag(noise_var)
    P = riccati(F, H, jnp.diag(q), R)
    K = P @ H.T @ jnp.linalg.inv(H @ P @ H.T + R)
    updated = P - K @ H @ P
    return F, H, K, 0.5 * (updated + updated.T)
