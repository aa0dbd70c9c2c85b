"""Fit candidate effects, batched: one vmapped optimistix Levenberg-Marquardt solve over all candidates.

Every candidate frees ``K`` entries of ``eta`` (``index[C, K]``, padded with a dummy slot), warm-started
from the base model (``eta`` at no effect, the base ``theta`` held fixed) at the effect's start values.
The residuals are the predictor's normalised output errors on the training flight (their sum of squares
is ``N`` times the summed per-channel gap), so the fit minimises the training gap directly. Standard
errors are Cramer-Rao style, ``s^2 (J^T J)^+`` with ``J`` the Jacobian at the optimum and
``s^2 = RSS / (N_res - K)``, inflated for coloured residuals by the AR(1) factor ``(1 + r1) / (1 - r1)``
(``r1``: the residuals' lag-1 autocorrelation, averaged over channels), i.e. counting effective samples.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import optimistix as optx

from .._types import Array, Float, Int
from ..cost import nmse
from .predictor import Predictor


def embed(base: Float[Array, "E"], index: Int[Array, "K"], z: Float[Array, "K"]) -> Float[Array, "E"]:
    """``eta``: ``base`` with the slots ``index`` set to ``z`` (slot ``E`` is a dummy that is dropped)."""
    return jnp.concatenate([base, jnp.zeros(1, base.dtype)]).at[index].set(z)[:-1]


class Fit(eqx.Module):
    """Fitted candidates: values ``z[C, K]``, standard errors, training RSS, solver steps, converged flags."""

    z: Float[Array, "C K"]
    stderr: Float[Array, "C K"]
    rss: Float[Array, "C"]
    steps: Int[Array, "C"]
    converged: Array


@eqx.filter_jit
def fit_candidates(
    pred: Predictor,
    theta: Float[Array, "40"],
    base: Float[Array, "E"],
    index: Int[Array, "C K"],
    start: Float[Array, "C K"],
    max_steps: int = 40,
) -> Fit:
    """Fit every candidate on ``pred``'s flight (vmapped LM; ``max_steps`` is static)."""
    solver = optx.LevenbergMarquardt(rtol=1e-6, atol=1e-8, linear_solver=lx.QR())

    def one(idx, z0):
        def residuals(z, _):
            return pred.residuals(theta, embed(base, idx, z))

        sol = optx.least_squares(residuals, solver, z0, max_steps=max_steps, throw=False)
        r0, r1 = residuals(z0, None), residuals(sol.value, None)
        better = jnp.all(jnp.isfinite(sol.value)) & (jnp.sum(r1**2) <= jnp.sum(r0**2))
        z = jnp.where(better, sol.value, z0)
        res = jnp.where(better, r1, r0)
        J = jax.jacfwd(residuals)(z, None)
        rss = jnp.sum(res**2)
        active = jnp.any(J != 0, axis=0)
        dof = res.shape[0] - jnp.sum(active)
        cov = rss / dof * _colour_factor(res.reshape(pred.measured.shape)) * jnp.linalg.pinv(J.T @ J)
        stderr = jnp.where(active, jnp.sqrt(jnp.abs(jnp.diag(cov))), 0.0)
        return z, stderr, rss, sol.stats["num_steps"], sol.result == optx.RESULTS.successful

    return Fit(*jax.vmap(one)(index, start))


def _colour_factor(res: Float[Array, "N k"]) -> Float[Array, ""]:
    """``(1 + r1) / (1 - r1)`` of the lag-1 autocorrelation ``r1`` (mean over channels, clipped to [0, 0.99])."""
    r1 = jnp.sum(res[1:] * res[:-1], axis=0) / jnp.maximum(jnp.sum(res**2, axis=0), 1e-300)
    r1 = jnp.clip(jnp.mean(r1), 0.0, 0.99)
    return (1.0 + r1) / (1.0 - r1)


@eqx.filter_jit
def score(
    pred: Predictor, theta: Float[Array, "40"], etas: Float[Array, "C E"]
) -> tuple[Float[Array, "C k"], Float[Array, "C S"]]:
    """Gap per channel (:func:`jaxheli.cost.nmse`) and residual energy per restart segment of each ``eta``."""
    y = jax.vmap(lambda eta: pred(theta, eta))(etas)
    return nmse(y, pred.measured), pred.segment_energy(y)
