"""Fit metrics between simulated and measured outputs: Pearson (paper Eq. 6-7), TIC, RMSE, fit %.

Every function takes ``sim[..., N, k]`` (any batch of candidates) and ``meas[N, k]`` and reduces over
time, one value per channel (``[..., k]``) or per candidate. A simulated channel that is non-finite or
flat scores as the worst value (Pearson -1, cost 4 per channel, TIC 1, RMSE inf, fit -inf), never NaN,
so a diverging candidate cannot poison a population.
"""

from __future__ import annotations

from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

from ._types import Array, ArrayLike, Bool, Float

SearchCost = Literal["pearson", "output-error"]
SEARCH_COSTS: tuple[str, ...] = ("pearson", "output-error")
"""Costs a population search can minimise: the paper's (:func:`paper_cost`) or :func:`output_error_cost`."""

WORST_RHO = -1.0
WORST_TIC = 1.0


def _pair(sim: ArrayLike, meas: ArrayLike) -> tuple[Array, Array]:
    sim = jnp.asarray(sim)
    meas = jnp.asarray(meas, dtype=sim.dtype)
    if sim.ndim < 2 or sim.shape[-2:] != meas.shape:
        raise ValueError(f"sim must be [..., N, k] with [N, k] = meas.shape {meas.shape}; got {sim.shape}")
    return sim, jnp.broadcast_to(meas, sim.shape)


def require_varying(meas: ArrayLike) -> None:
    """Raise where a measured channel (last axis) is constant: it has no correlation. Checked on the host, for a
    concrete ``meas``; a traced one is the target of a :class:`~jaxheli.problem.Problem`, whose constructor checks
    it (a check inside the compiled program would be a host callback, and XLA's persistent cache does not store a
    program that holds one)."""
    if not isinstance(meas, jax.core.Tracer):
        values = np.asarray(meas)
        if np.any(np.ptp(values.reshape(-1, values.shape[-1]), axis=0) <= 0):
            raise ValueError("pearson: a measured channel is constant")


def _bad_channels(sim: Array) -> Bool[Array, "*batch k"]:
    """Channels with any non-finite sample, or flat to within rounding."""
    finite = jnp.all(jnp.isfinite(sim), axis=-2)
    safe = jnp.where(jnp.isfinite(sim), sim, 0.0)
    centred = safe - jnp.mean(safe, axis=-2, keepdims=True)
    spread = jnp.sum(centred**2, axis=-2)
    scale = jnp.max(jnp.abs(safe), axis=-2)
    n = sim.shape[-2]
    flat = spread <= n * (100 * jnp.finfo(sim.dtype).eps * scale) ** 2
    return ~finite | flat | ~jnp.isfinite(spread)


def pearson(sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch k"]:
    """Pearson correlation per channel (paper Eq. 6); worst (-1) for non-finite or flat simulations.

    A constant measured channel has no correlation and raises (:func:`require_varying`).
    """
    pair = _pair(sim, meas)
    require_varying(meas)
    sim, meas = pair
    bad = _bad_channels(sim)
    s = jnp.where(bad[..., None, :], 0.0, sim)
    sc = s - jnp.mean(s, axis=-2, keepdims=True)
    mc = meas - jnp.mean(meas, axis=-2, keepdims=True)
    m_spread = jnp.sum(mc**2, axis=-2)
    return pearson_from_sums(jnp.sum(sc * mc, axis=-2), jnp.sum(sc**2, axis=-2), m_spread, bad)


def pearson_from_sums(
    cross: Float[Array, "*batch k"],
    s_spread: Float[Array, "*batch k"],
    m_spread: Float[Array, "*#batch k"],
    bad: Bool[Array, "*batch k"],
) -> Float[Array, "*batch k"]:
    """Pearson's rho from centred sums: ``cross = sum (s - mean s)(m - mean m)``, ``s_spread = sum (s - mean
    s)^2``, ``m_spread`` likewise for the measurement; worst (-1) where ``bad`` or not finite, clipped to
    [-1, 1]. The one place both the per-sample and the blocked (sums-only) costs turn sums into rho."""
    s_spread = jnp.where(bad, 1.0, s_spread)
    rho = jnp.where(bad, 0.0, cross) / jnp.sqrt(s_spread * m_spread)
    rho = jnp.where(bad | ~jnp.isfinite(rho), WORST_RHO, rho)
    return jnp.clip(rho, -1.0, 1.0)


def flat_from_sums(
    s_spread: Float[Array, "*batch k"], mean_square: Float[Array, "*batch k"], n: int
) -> Bool[Array, "*batch k"]:
    """Flat to within rounding, from sums alone: ``sum (s - mean)^2 <= n (100 eps)^2 rms^2``, or not finite.

    The per-sample test in :func:`pearson` scales by ``max |s|``; without the samples the root mean square
    stands in (a smaller scale, so this flags no more channels than that test does).
    """
    eps = jnp.finfo(s_spread.dtype).eps
    flat = s_spread <= n * (100 * eps) ** 2 * mean_square
    return flat | ~jnp.isfinite(s_spread) | ~jnp.isfinite(mean_square)


def paper_cost(sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch"]:
    """The paper's cost ``C = sum_i (1 - rho_i)^2`` over the channels (Eq. 7); 0 is a perfect shape match."""
    return jnp.sum((1.0 - pearson(sim, meas)) ** 2, axis=-1)


def rmse(sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch k"]:
    """Root-mean-square error per channel, in the channel's units; inf when non-finite."""
    sim, meas = _pair(sim, meas)
    err = jnp.sqrt(jnp.mean((sim - meas) ** 2, axis=-2))
    return jnp.where(jnp.isfinite(err), err, jnp.inf)


def tic(sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch k"]:
    """Theil inequality coefficient per channel, in [0, 1]; <= 0.25-0.3 is a good time-domain match."""
    sim, meas = _pair(sim, meas)
    num = jnp.sqrt(jnp.mean((sim - meas) ** 2, axis=-2))
    den = jnp.sqrt(jnp.mean(sim**2, axis=-2)) + jnp.sqrt(jnp.mean(meas**2, axis=-2))
    value = num / jnp.where(den > 0, den, 1.0)
    ok = jnp.isfinite(value) & (den > 0)
    return jnp.where(ok, jnp.clip(value, 0.0, 1.0), WORST_TIC)


def fit_percent(sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch k"]:
    """Normalised fit ``100 (1 - |y - m| / |m - mean(m)|)`` per channel (MATLAB ``compare``); -inf if non-finite."""
    sim, meas = _pair(sim, meas)
    num = jnp.sqrt(jnp.sum((sim - meas) ** 2, axis=-2))
    den = jnp.sqrt(jnp.sum((meas - jnp.mean(meas, axis=-2, keepdims=True)) ** 2, axis=-2))
    value = 100.0 * (1.0 - num / den)
    return jnp.where(jnp.isfinite(value), value, -jnp.inf)


def nmse(sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch k"]:
    """Normalised residual energy ``sum (y - m)^2 / sum (m - mean(m))^2`` per channel: the sim-to-real gap.

    0 for a perfect model, 1 for predicting the channel's mean; amplitude-sensitive (unlike Pearson);
    ``inf`` if the simulation is non-finite.
    """
    sim, meas = _pair(sim, meas)
    num = jnp.sum((sim - meas) ** 2, axis=-2)
    den = jnp.sum((meas - jnp.mean(meas, axis=-2, keepdims=True)) ** 2, axis=-2)
    value = num / den
    return jnp.where(jnp.isfinite(value), value, jnp.inf)


def output_error_cost(sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch"]:
    """Sum over the channels of :func:`nmse`: squared output errors, each channel normalised by its measured
    variance (so units do not weigh); 0 is a perfect match, 1 per channel predicts the channel's mean."""
    return jnp.sum(nmse(sim, meas), axis=-1)


def search_cost(kind: SearchCost, sim: ArrayLike, meas: ArrayLike) -> Float[Array, "*batch"]:
    """The search cost ``kind`` (:data:`SEARCH_COSTS`) of ``sim[..., N, k]`` against ``meas[N, k]``."""
    if kind == "pearson":
        return paper_cost(sim, meas)
    if kind == "output-error":
        return output_error_cost(sim, meas)
    raise ValueError(f"search cost must be one of {SEARCH_COSTS}, got {kind!r}")


def metrics(sim: ArrayLike, meas: ArrayLike, names: tuple[str, ...] | list[str]) -> dict[str, object]:
    """All metrics of one simulation ``sim[N, k]`` as plain floats: ``{metric: {channel: value}}`` and ``cost``."""
    sim, meas = _pair(sim, meas)
    if sim.ndim != 2 or len(names) != sim.shape[-1]:
        raise ValueError(f"metrics: need one simulation [N, k] and k names; got {sim.shape} and {len(names)} names")
    out: dict[str, object] = {}
    for key, fn in (("pearson", pearson), ("tic", tic), ("rmse", rmse), ("fit_percent", fit_percent)):
        values = fn(sim, meas)
        out[key] = {n: float(v) for n, v in zip(names, values)}
    out["cost"] = float(paper_cost(sim, meas))
    return out
