"""Runs whose initial states are estimated: multiple shooting by variable projection.

An open-loop-unstable model simulated over a long record amplifies any error in its initial state; restarting from
the *measured* states instead (the simulator's ``x0="measured"`` restarts) injects the sensors' noise into every
run. Here every run (the whole record, or each ``segment`` of it) starts from the state that best explains that
run's measured outputs under ``theta``. The outputs are affine in a run's initial state,

    y_j[m] = f_j[m] + C Ad^m x_j,

with ``f_j`` the response to the sticks from rest, so each ``x_j`` is a small weighted linear least-squares fit
(weights: each measured channel's inverse variance over the record, the normalisation of PEM's residuals), solved
inside the simulation and differentiated through: Golub and Pereyra's variable projection. The initial states are
nuisance parameters eliminated exactly; what is left depends on ``theta`` alone, is the maximum-likelihood output
error for white measurement noise, and its Jacobian gives the parameters' Cramer-Rao bounds with the initial states
marginalised.

Layout (the simulator's restarts): run 0 covers samples ``0 .. L`` (``m = 0 .. L``), run ``j >= 1`` samples
``jL + 1 .. (j + 1) L`` (``m = 1 .. L``), the last one cut at the record's end; ``L`` is the segment length in
samples (the whole record for one run). ``C Ad^m`` is built once for ``m = 0 .. L`` by a scan of 13 x 13
products and shared by every run. Channels the simulator cannot restart from (unmeasured, or the authors'
stick-multiple flapping columns) get no weight.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from .._types import Array, Float
from ..model import build_ab, output_indices
from .discretize import discretize

Simulator = Any
"""A :class:`jaxheli.sim.simulate.Simulator` (which calls this module; not imported here, so no import cycle)."""

RIDGE = 1e-10
"""Tikhonov term of each run's normal equations, relative to their mean diagonal: a state the run's outputs cannot
see (e.g. the yaw-gyro state of a model without feedback) is set to zero instead of making the solve singular."""


def run_layout(n_samples: int, segment_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """``(sample, valid)``, each ``[K, L + 1]``: the sample index of step ``m`` of run ``j`` and whether it belongs
    to that run (see the module); ``segment_samples`` 0 means one run over the record."""
    L = segment_samples if segment_samples > 0 else n_samples - 1
    L = max(L, 1)
    K = max(1, -(-(n_samples - 1) // L))
    j, m = np.meshgrid(np.arange(K), np.arange(L + 1), indexing="ij")
    sample = j * L + m
    valid = ((m >= 1) | (j == 0)) & (sample <= n_samples - 1)
    return np.where(valid, sample, n_samples), valid


def run_count(n_samples: int, segment_samples: int) -> int:
    """Runs of a record of ``n_samples`` restarted every ``segment_samples`` (0: one run)."""
    return int(run_layout(n_samples, segment_samples)[1].shape[0])


def run_states(sim: Simulator, theta: Float[Array, "40"]) -> Float[Array, "K 13"]:
    """Each run's least-squares initial state under ``theta[40]`` (the states :func:`estimated_outputs` starts
    from), in :data:`jaxheli.model.STATE_NAMES` order."""
    return _project(sim, theta)[1]


def estimated_outputs(sim: Simulator, theta: Float[Array, "40"]) -> Float[Array, "N k"]:
    """``sim``'s outputs for one ``theta[40]``, every run started from its least-squares initial state."""
    forced, x0, powers = _project(sim, theta)
    n, k = forced.shape
    sample, _ = run_layout(n, sim.segment_samples)
    free = jnp.einsum("mkx,jx->jmk", powers, x0)  # [K, L + 1, k]
    flat = jnp.zeros((n + 1, k), forced.dtype).at[sample.ravel()].add(free.reshape(-1, k))
    return forced + flat[:n]


def _project(sim: Simulator, theta: Float[Array, "40"]) -> tuple[Array, Array, Array]:
    """The response from rest ``[N, k]``, each run's least-squares initial state ``[K, 13]`` and ``C Ad^m``
    ``[L + 1, k, 13]``."""
    idx = output_indices(sim.outputs)
    measured = sim.measured_states[:, idx]
    std = jnp.std(measured, axis=0)
    used = jnp.asarray(np.asarray(sim.measured_mask)[idx]) & (std > 0)
    weight = jnp.where(used, 1.0 / jnp.where(std > 0, std, 1.0) ** 2, 0.0)

    zeros = jnp.zeros_like(sim.measured_states)
    from_rest = dataclasses.replace(sim, measured_states=zeros, x0=zeros[0], initial="given", reset="zero")
    forced = from_rest._one(theta)  # every run from rest
    d = discretize(*build_ab(theta, sim.g), sim.dt, sim.hold)
    eye = jnp.eye(d.Ad.shape[0], dtype=d.Ad.dtype)
    sample, valid = run_layout(measured.shape[0], sim.segment_samples)

    def power(M, _):
        return d.Ad @ M, M[idx]  # C Ad^m

    _, powers = jax.lax.scan(power, eye, None, length=sample.shape[1])  # [L + 1, k, 13]
    padded = jnp.concatenate([measured - forced, jnp.zeros((1, idx.size), forced.dtype)])
    error = padded[sample]  # [K, L + 1, k]; zero where a step is not in the run
    weighted = powers * weight[None, :, None]
    gram = jnp.einsum("jm,mkx,mky->jxy", jnp.asarray(valid, forced.dtype), weighted, powers)  # [K, 13, 13]
    rhs = jnp.einsum("jmk,mkx->jx", error, weighted)
    scale = RIDGE * jnp.trace(gram, axis1=-2, axis2=-1) / eye.shape[0] + jnp.finfo(gram.dtype).tiny
    x0 = jnp.linalg.solve(gram + scale[:, None, None] * eye[None], rhs[..., None])[..., 0]
    return forced, x0, powers
