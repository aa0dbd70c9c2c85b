"""Least-squares estimate of the initial state of a record (what MATLAB's ``compare`` does).

The simulated outputs are affine in ``x0``: ``y(x0) = y(0) + G x0`` with ``G`` the free response to each
unit initial state. ``x0`` is the least-squares fit of ``G x0`` to ``measured - y(0)`` over the record
(or its first ``horizon`` seconds), one small linear solve.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from .._xla import QUICK_COMPILE
from ..data.flight import FlightData
from ..model import N_STATES
from .simulate import Simulator, make_simulator


def estimate_x0(
    theta: Float[Array, "40"], data: FlightData | Any, *, horizon: float | None = None, **options
) -> Float[np.ndarray, "13"]:
    """Initial 13-state vector that best explains the record's outputs under ``theta``.

    ``data`` is a flight with :func:`jaxheli.make_simulator`'s ``options`` (``outputs``, ``hold``, ``g``), or
    a :class:`jaxheli.problem.Problem` (no options: its channels, hold and g hold). The fit uses a single
    open-loop run. ``horizon`` (s) limits the fit to the start of the record, which keeps the problem
    well conditioned for open-loop-unstable models on long records.
    """
    options = {k: v for k, v in options.items() if k not in ("x0", "segment", "reset")}
    if isinstance(data, FlightData):
        sim = make_simulator(data, **options)
        target = jnp.asarray(data.select(sim.outputs).outputs)
    elif options:
        raise ValueError(f"estimate_x0: options {sorted(options)} go with a flight, not a Problem")
    else:
        sim, target = data.sim, data.target
    return np.asarray(_fit_x0(jnp.asarray(theta), open_loop(sim), target, horizon))


def open_loop(sim: Simulator) -> Simulator:
    """``sim`` as one open-loop run from rest (no restarts), its channels, hold and g kept."""
    return sim.configure(outputs=sim.outputs, g=sim.g, hold=sim.hold)


@eqx.filter_jit(compiler_options=QUICK_COMPILE)
def _fit_x0(theta: Array, sim: Simulator, target: Array, horizon: float | None) -> Array:
    if horizon is not None:
        n = max(2, min(sim.inputs.shape[0], int(round(horizon / sim.dt)) + 1))
        sim = dataclasses.replace(sim, inputs=sim.inputs[:n], measured_states=sim.measured_states[:n])
        target = target[:n]
    forced = sim(theta)
    free = dataclasses.replace(sim, inputs=jnp.zeros_like(sim.inputs))

    def unit_response(e: Array) -> Array:
        return free.replace_x0(e)(theta)

    G = jax.vmap(unit_response)(jnp.eye(N_STATES, dtype=theta.dtype))  # [13, N, k]
    G = jnp.moveaxis(G, 0, -1).reshape((-1, N_STATES))
    rhs = (target - forced).reshape(-1)
    ok = jnp.all(jnp.isfinite(G)) & jnp.all(jnp.isfinite(rhs))
    x0, *_ = jnp.linalg.lstsq(jnp.where(ok, G, 0.0), jnp.where(ok, rhs, 0.0))
    return x0
