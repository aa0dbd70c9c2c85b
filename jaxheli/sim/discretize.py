"""Exact discretisation of ``x' = A x + B u`` under zero- or first-order hold of the inputs."""

from __future__ import annotations

from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp

from .._types import Array, Float

Hold = Literal["zoh", "foh"]


class Discrete(eqx.Module):
    """Discrete model ``x[k+1] = Ad x[k] + B0 u[k] + B1 u[k+1]`` (batched over leading axes).

    Zero-order hold has ``B1 = 0``; first-order hold (inputs linear between samples, what MATLAB's
    ``lsim`` uses for smooth inputs) splits the input effect between both ends of the step.
    """

    Ad: Float[Array, "*batch n n"]
    B0: Float[Array, "*batch n m"]
    B1: Float[Array, "*batch n m"]


def discretize(
    A: Float[Array, "*batch n n"], B: Float[Array, "*batch n m"], dt: float, hold: Hold = "zoh"
) -> Discrete:
    """Discretise continuous ``(A, B)`` at sample time ``dt`` (s) by one matrix exponential.

    ZOH: ``expm([[A, B], [0, 0]] dt)``. FOH: ``expm([[A, B, 0], [0, 0, I/dt], [0, 0, 0]] dt)`` gives
    ``Phi``, ``Gamma1 = int_0^dt e^{As} ds B`` and ``Gamma2`` with ``x+ = Phi x + (Gamma1 - Gamma2) u_k
    + Gamma2 u_{k+1}``.
    """
    if hold not in ("zoh", "foh"):
        raise ValueError(f"discretize: hold must be 'zoh' or 'foh', got {hold!r}")
    A = jnp.asarray(A)
    B = jnp.asarray(B)
    n, m = B.shape[-2], B.shape[-1]
    batch = jnp.broadcast_shapes(A.shape[:-2], B.shape[:-2])
    A = jnp.broadcast_to(A, batch + (n, n))
    B = jnp.broadcast_to(B, batch + (n, m))
    dtype = jnp.result_type(A, B)
    if hold == "zoh":
        top = jnp.concatenate([A, B], axis=-1)
        M = jnp.concatenate([top, jnp.zeros(batch + (m, n + m), dtype)], axis=-2)
        E = _expm(M * dt)
        return Discrete(E[..., :n, :n], E[..., :n, n:], jnp.zeros(batch + (n, m), dtype))
    eye = jnp.broadcast_to(jnp.eye(m, dtype=dtype), batch + (m, m))
    zn = jnp.zeros(batch + (m, n), dtype)
    zm = jnp.zeros(batch + (m, m), dtype)
    M = jnp.concatenate(
        [
            jnp.concatenate([A, B, jnp.zeros(batch + (n, m), dtype)], axis=-1),
            jnp.concatenate([zn, zm, eye / dt], axis=-1),
            jnp.concatenate([zn, zm, zm], axis=-1),
        ],
        axis=-2,
    )
    E = _expm(M * dt)
    gamma1 = E[..., :n, n : n + m]
    gamma2 = E[..., :n, n + m :]
    return Discrete(E[..., :n, :n], gamma1 - gamma2, gamma2)


def _expm(M: Array) -> Array:
    """Matrix exponential over any leading batch axes."""
    flat = M.reshape((-1,) + M.shape[-2:])
    return jax.vmap(jax.scipy.linalg.expm)(flat).reshape(M.shape)
