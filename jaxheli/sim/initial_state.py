"""Least-squares estimate of the initial state of a record (what MATLAB's ``compare`` does).

The simulated outputs are affine in ``x0``: ``y(x0) = y(0) + G x0`` with ``G`` the free response to each
unit initial state. ``x0`` is the least-squares fit of ``G x0`` to ``measured - y(0)`` over the record
(or its first ``horizon`` seconds), one small linear solve.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..data.flight import FlightData
from ..model import N_STATES
from .simulate import make_simulator


def estimate_x0(
    theta: Float[Array, "40"], flight: FlightData, *, horizon: float | None = None, **options
) -> Float[np.ndarray, "13"]:
    """Initial 13-state vector that best explains ``flight``'s outputs under ``theta``.

    ``options`` are :func:`jaxheli.make_simulator`'s (``outputs``, ``hold``, ``g``); the fit uses a single
    open-loop run. ``horizon`` (s) limits the fit to the start of the record, which keeps the problem
    well conditioned for open-loop-unstable models on long records.
    """
    options = {k: v for k, v in options.items() if k not in ("x0", "segment", "reset")}
    if horizon is not None:
        n = max(2, min(flight.n_samples, int(round(horizon / flight.dt)) + 1))
        flight = flight.replace(time=flight.time[:n], inputs=flight.inputs[:n], outputs=flight.outputs[:n])
    sim = make_simulator(flight, **options)
    target = jnp.asarray(flight.select(sim.outputs).outputs)
    theta = jnp.asarray(theta)
    forced = sim(theta)
    zero_inputs = flight.replace(inputs=np.zeros_like(flight.inputs))
    free = make_simulator(zero_inputs, **options)

    def unit_response(e: Array) -> Array:
        return free.replace_x0(e)(theta)

    G = jax.vmap(unit_response)(jnp.eye(N_STATES, dtype=theta.dtype))  # [13, N, k]
    G = jnp.moveaxis(G, 0, -1).reshape((-1, N_STATES))
    rhs = (target - forced).reshape(-1)
    ok = jnp.all(jnp.isfinite(G)) & jnp.all(jnp.isfinite(rhs))
    x0, *_ = jnp.linalg.lstsq(jnp.where(ok, G, 0.0), jnp.where(ok, rhs, 0.0))
    return np.asarray(x0)
