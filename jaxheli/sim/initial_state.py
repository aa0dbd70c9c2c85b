"""Least-squares estimate of the initial state of a record (what MATLAB's ``compare`` does).

The simulated outputs are affine in ``x0``: ``y(x0) = y(0) + G x0`` with ``G`` the free response to each
unit initial state. ``x0`` is the least-squares fit of ``G x0`` to ``measured - y(0)`` over the record
(or its first ``horizon`` seconds), one small linear solve. With ``bias`` a constant offset per channel is fitted
beside ``x0`` (``k`` more columns, each 1 on its channel's samples): the start of a run in time-domain verification
(Tischler and Remple, ch. 14), where the sensors' offsets would otherwise be charged to the model.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from .._xla import quick_jit
from ..data.flight import FlightData
from ..model import N_STATES
from .simulate import Simulator, make_simulator


@dataclasses.dataclass(frozen=True)
class Start:
    """A record's least-squares start: initial state ``x0[13]`` (:data:`jaxheli.model.STATE_NAMES` order) and
    output bias ``bias[k]`` per scored channel, in the channel's units (zero unless estimated)."""

    x0: Float[np.ndarray, "13"]
    bias: Float[np.ndarray, "k"]


def estimate_x0(
    theta: Float[Array, "40"], data: FlightData | Any, *, horizon: float | None = None, **options
) -> Float[np.ndarray, "13"]:
    """Initial 13-state vector that best explains the record's outputs under ``theta`` (:func:`estimate_start`
    without a bias)."""
    return estimate_start(theta, data, horizon=horizon, **options).x0


def estimate_start(
    theta: Float[Array, "40"], data: FlightData | Any, *, horizon: float | None = None, bias: bool = False,
    **options,
) -> Start:
    """Initial 13-state vector, and with ``bias`` a constant output offset per channel, that best explain the
    record's outputs under ``theta`` (unweighted least squares over every scored sample).

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
        raise ValueError(f"estimate_start: options {sorted(options)} go with a flight, not a Problem")
    else:
        sim, target = data.sim, data.target
    x0, offset = _fit_x0(jnp.asarray(theta), open_loop(sim), target, horizon, bias)
    return Start(np.asarray(x0), np.asarray(offset))


def open_loop(sim: Simulator) -> Simulator:
    """``sim`` as one open-loop run from rest (no restarts), its channels, hold and g kept."""
    return sim.configure(outputs=sim.outputs, g=sim.g, hold=sim.hold)


@quick_jit
def _fit_x0(theta: Array, sim: Simulator, target: Array, horizon: float | None, bias: bool) -> tuple[Array, Array]:
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
    n, k = target.shape
    if bias:
        G = jnp.concatenate([G, jnp.tile(jnp.eye(k, dtype=G.dtype), (n, 1))], axis=1)
    rhs = (target - forced).reshape(-1)
    ok = jnp.all(jnp.isfinite(G)) & jnp.all(jnp.isfinite(rhs))
    solution, *_ = jnp.linalg.lstsq(jnp.where(ok, G, 0.0), jnp.where(ok, rhs, 0.0))
    return solution[:N_STATES], solution[N_STATES:] if bias else jnp.zeros(k, solution.dtype)
